"""Cryptomatte 1.2 layers: anti-aliased id mattes that Nuke's and Blender's Cryptomatte nodes read.

The specification (Friedman and Jones, *Fully Automatic ID Mattes with Support for Motion Blur
and Transparency*, Psyop 2015; the Cryptomatte 1.2 specification) asks for:

- an id per name: ``MurmurHash3_x86_32`` (seed 0) of its UTF-8 bytes, read as the bits of a
  float32; a hash whose exponent bits are 0 or 255 (a denormal, an infinity or a NaN) gets bit 23
  flipped first, as the specification's reference code does;
- per pixel, the ids seen in it ranked by *coverage* (their share of the pixel's filtered
  samples), highest first, stored two ranks per RGBA layer: ``{name}00.R`` = id of rank 0,
  ``.G`` = its coverage, ``.B``/``.A`` = rank 1; ``{name}01`` ranks 2 and 3, and so on;
- metadata ``cryptomatte/<key>/name`` (the layer name), ``/hash`` (``MurmurHash3_32``),
  ``/conversion`` (``uint32_to_float32``) and ``/manifest`` (JSON: name -> 8 hex digits of the
  float's bits), where ``<key>`` is the first 7 hex digits of the MurmurHash3 of the layer name.

Two layers are written: ``CryptoObject`` (shape names, as in the object table) and
``CryptoMaterial`` (each shape's BSDF: its XML ``id``, so shapes that share a referenced BSDF
share the matte; an unnamed nested BSDF is named ``<shape>.bsdf``).

**Coverage** comes from the film's own samples and reconstruction filter, not from pixel centres:
the film's sampler (forked, seeded with ``seed``) draws ``spp`` jittered positions in every
pixel, one ray each (:func:`mi_npr.raycast.pixel_rays`: lens centre, mid-shutter), and a sample at
film position ``s`` adds ``f(s.x - c.x) f(s.y - c.y)`` to every pixel of centre ``c`` within the
filter's radius, as Mitsuba's film splats it (``f`` = the film's ``rfilter.eval``; negative lobes
of Lanczos or Mitchell are clamped to 0, coverage cannot be negative). Each pixel's weights are
then divided by its total weight, background included, so the coverages of a pixel that the
scene covers entirely sum to 1, and of one on the silhouette to the covered share. Which pixels
a sample reaches follows the filter: the box filter (radius 0.5) keeps every sample in its
pixel, Mitsuba's default Gaussian (stddev 0.5, radius 2) spreads it over 5 x 5 pixels.
"""

from __future__ import annotations

import json
import math
import os
import struct
from collections.abc import Mapping, Sequence
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from . import layers as L
from .errors import ParameterError
from .gbuffer import GBuffer, to_numpy
from .raycast import cast, pixel_rays
from .render import render_gbuffer
from .scene import ObjectTable, merge_defines, object_table, sensor_of
from .session import SceneSession

OBJECT = L.CRYPTO_OBJECT
MATERIAL = L.CRYPTO_MATERIAL
#: Ranks stored per pixel by default (3 RGBA layers), as Nuke's and Blender's writers do.
DEFAULT_LEVELS = 6
#: Coverage cells (pixels x names, float32) accumulated at once: the film is ranked in bands of
#: rows of at most this many cells (64 MB), a row at least.
BAND_CELLS = 1 << 24
#: The most cells of one row (a band of one row): beyond this, too many names is an error.
_MAX_CELLS = 1 << 27
#: Most samples cast at once for the coverage (about a million: some 100 MB of rays and hits).
SAMPLES_PER_PASS = 1 << 20
#: The seeds of the passes after the first, ``seed + p * step``: far apart, so two renders with
#: nearby seeds share no pass.
_PASS_SEED_STEP = 0x9E3779B1


def murmurhash3_32(data: bytes | str, seed: int = 0) -> int:
    """MurmurHash3_x86_32 (Austin Appleby's reference algorithm) as an unsigned int."""
    if isinstance(data, str):
        data = data.encode("utf-8")
    c1, c2, mask = 0xCC9E2D51, 0x1B873593, 0xFFFFFFFF
    h = seed & mask
    n = len(data) // 4 * 4
    for (k,) in struct.iter_unpack("<I", data[:n]):
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        k = (k * c2) & mask
        h ^= k
        h = ((h << 13) | (h >> 19)) & mask
        h = (h * 5 + 0xE6546B64) & mask
    tail = data[n:]
    if tail:
        k = int.from_bytes(tail, "little")
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        k = (k * c2) & mask
        h ^= k
    h ^= len(data)
    h ^= h >> 16
    h = (h * 0x85EBCA6B) & mask
    h ^= h >> 13
    h = (h * 0xC2B2AE35) & mask
    h ^= h >> 16
    return h


def id_bits(name: str) -> int:
    """The float32 bits of ``name``'s Cryptomatte id (no denormal, infinity or NaN)."""
    h = murmurhash3_32(name)
    exponent = (h >> 23) & 0xFF
    if exponent in (0, 255):
        h ^= 1 << 23
    return h


def name_id(name: str) -> float:
    """``name``'s Cryptomatte id as a float (the value stored in the id channels)."""
    return float(np.array([id_bits(name)], np.uint32).view(np.float32)[0])


def layer_key(layer: str) -> str:
    """The metadata key of a Cryptomatte layer: 7 hex digits of MurmurHash3 of its name."""
    return f"{murmurhash3_32(layer):08x}"[:7]


def manifest(names: Sequence[str]) -> str:
    """The ``manifest`` metadata: JSON object name -> 8 hex digits of the id's float bits."""
    return json.dumps({n: f"{id_bits(n):08x}" for n in sorted(set(names))}, ensure_ascii=False)


def metadata(layer: str, names: Sequence[str]) -> dict[str, str]:
    """The four ``cryptomatte/<key>/...`` attributes of one layer."""
    prefix = f"cryptomatte/{layer_key(layer)}/"
    return {
        prefix + "name": layer,
        prefix + "hash": "MurmurHash3_32",
        prefix + "conversion": "uint32_to_float32",
        prefix + "manifest": manifest(names),
    }


def material_names(table: ObjectTable) -> dict[int, str]:
    """Object id -> the name of its shape's BSDF (XML ``id``, else ``<shape>.bsdf``): the object
    table's material naming (:meth:`~mi_npr.scene.ObjectTable.material_names`)."""
    return table.material_names()


# ------------------------------------------------------------------------------------- coverage
def _samples(
    scene: mi.Scene,
    sensor: mi.Sensor,
    table: ObjectTable,
    spp: int,
    seed: int,
    rows: tuple[int, int] | None = None,
) -> tuple[mi.Float, mi.Float, mi.UInt32]:
    """Film positions (x, y) of ``spp`` jittered samples per pixel of the film's ``rows``
    (``(first, stop)``; default all) and the object id each sees. Sample ``i`` belongs to the
    ``i // spp``-th pixel of those rows (raster order), as in Mitsuba's wavefront."""
    w, h = (int(v) for v in sensor.film().crop_size())
    r0, r1 = rows if rows is not None else (0, h)
    n = w * (r1 - r0) * spp
    sampler = sensor.sampler().fork()
    sampler.set_sample_count(spp)
    sampler.set_samples_per_wavefront(spp)
    sampler.seed(seed, n)
    u = sampler.next_2d()
    idx = dr.arange(mi.UInt32, n) // spp
    x = mi.Float(idx % w) + u.x
    y = mi.Float(idx // w + r0) + u.y
    ids = cast(scene, pixel_rays(sensor, x, y), table).object_id  # a pixel's rays side by side
    dr.eval(x, y, ids)
    return x, y, ids


def coverage(
    x: Any,
    y: Any,
    ids: Any,
    n_ids: int,
    width: int,
    height: int,
    rfilter: mi.ReconstructionFilter,
) -> np.ndarray:
    """Per-pixel filtered share of every id: (H * W, n_ids + 1) float64, column 0 the
    background; each row sums to 1 (or is 0 where no sample reaches the pixel).

    ``x``, ``y``: film positions of the samples (``mi.Float`` or numpy), ``ids`` their ids
    (0..n_ids). A sample adds ``f(x - cx) f(y - cy)`` (``rfilter.eval``, clamped at 0) to each
    pixel of centre ``(cx, cy)`` within the filter's radius.
    """
    acc = dr.zeros(mi.Float, check_cells(width, height, n_ids))
    _accumulate(acc, x, y, ids, n_ids, width, height, rfilter)
    pixel, col, share = _shares(acc, 0, width * height, n_ids)
    out = np.zeros((width * height, n_ids + 1))
    out[pixel, col] = share
    return out


def _shares(
    acc: Any, first: int, pixels: int, n_ids: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The accumulated weights ``acc`` of ``pixels`` pixels (``pixels x (n_ids + 1)`` cells)
    as each pixel's shares (summing to 1 over its row, background included): the nonzero
    cells only, as ``(pixel, column, share)`` with the pixels numbered from ``first``."""
    nz = dr.compress(acc > 0)
    cell = to_numpy(nz).astype(np.int64)
    weight = to_numpy(dr.gather(mi.Float, acc, nz)).astype(np.float64)
    pixel, col = np.divmod(cell, n_ids + 1)
    total = np.bincount(pixel, weight, minlength=pixels)
    return pixel + first, col, weight / total[pixel]


def check_cells(width: int, rows: int, n_ids: int) -> int:
    """The cells of a coverage table of ``rows`` rows of ``width`` pixels and ``n_ids`` names
    held at once, or a :class:`ParameterError` when they are more than ``_MAX_CELLS`` (checked
    before a render starts: :func:`cryptomatte` holds a band of rows, :data:`BAND_CELLS` cells
    at most and one row at least; :func:`coverage` the whole table)."""
    cells = width * rows * (n_ids + 1)
    if cells > _MAX_CELLS:
        raise ParameterError(
            f"cryptomatte: {width}x{rows} pixels x {n_ids + 1} names is too many to rank "
            f"({cells} cells, at most {_MAX_CELLS})"
        )
    return cells


def _reach(rfilter: mi.ReconstructionFilter) -> int:
    """The pixels a sample reaches on each side of its own (the filter's radius)."""
    return max(0, math.ceil(float(rfilter.radius()) - 0.5))


def _accumulate(
    acc: Any,
    x: Any,
    y: Any,
    ids: Any,
    n_ids: int,
    width: int,
    height: int,
    rfilter: mi.ReconstructionFilter,
    first_row: int = 0,
    group: int = 1,
) -> None:
    """Add the filter weights of samples ``(x, y, ids)`` to the coverage table ``acc`` of the
    film's rows ``first_row`` to ``first_row + height`` (those rows' pixels x names).

    The samples are taken ``group`` at a time, one thread each group (a pixel's samples, as
    :func:`_samples` orders them): the weights of the samples that lie in the pixel of the
    group's first sample and see its id are summed in the thread, one sum per pixel the filter
    reaches, and added to the table once per group; every other sample is added on its own.
    The sums are the same for any order and grouping of the samples (up to float rounding);
    grouping a pixel's samples turns ``group`` atomic additions into one."""
    x, y, ids = mi.Float(x), mi.Float(y), mi.UInt32(ids)
    n = dr.width(ids)
    radius = float(rfilter.radius())
    reach = _reach(rfilter)
    offsets = range(-reach, reach + 1)
    # the band's rows and the sample count as kernel inputs, not constants: every band and
    # pass runs the same kernels
    first_row, height = dr.opaque(mi.Int32, first_row), dr.opaque(mi.Int32, height)

    def weight(d: Any) -> Any:
        return dr.select(dr.abs(d) < radius, dr.maximum(rfilter.eval(d), 0.0), 0.0)

    def cells(px: Any, py: Any, oid: Any) -> list[tuple[Any, Any]]:
        """The table cell and whether it is in the band, of each pixel the filter reaches
        from pixel ``(px, py)``, for id ``oid`` (the offsets row by row)."""
        out = []
        for dy in offsets:
            qy = py + dy - first_row
            for dx in offsets:
                qx = px + dx
                ok = (qx >= 0) & (qx < width) & (qy >= 0) & (qy < height)
                out.append(((mi.UInt32(qy) * width + mi.UInt32(qx)) * (n_ids + 1) + oid, ok))
        return out

    # the group size and sample count as kernel inputs too: every pass runs the same kernels
    size, limit = dr.opaque(mi.UInt32, n), dr.opaque(mi.UInt32, group)
    base = dr.arange(mi.UInt32, (n + group - 1) // group) * limit
    major = dr.gather(mi.UInt32, ids, base)
    mx = mi.Int32(dr.floor(dr.gather(mi.Float, x, base)))
    my = mi.Int32(dr.floor(dr.gather(mi.Float, y, base)))
    sums = [dr.zeros(mi.Float, dr.width(base)) for _ in range(len(offsets) ** 2)]
    step = dr.zeros(mi.UInt32, dr.width(base))

    def cond(step: Any, sums: list) -> Any:
        return step < limit

    def body(step: Any, sums: list) -> tuple[Any, list]:
        j = base + step
        live = j < size
        xs = dr.gather(mi.Float, x, j, live)
        ys = dr.gather(mi.Float, y, j, live)
        oid = dr.gather(mi.UInt32, ids, j, live)
        px, py = mi.Int32(dr.floor(xs)), mi.Int32(dr.floor(ys))
        mine = live & (oid == major) & (px == mx) & (py == my)
        # the filter is separable: 2 reach + 1 weights per axis, each pixel offset a product
        wx = [weight(xs - (mi.Float(px + dx) + 0.5)) for dx in offsets]
        wy = [weight(ys - (mi.Float(py + dy) + 0.5)) for dy in offsets]
        wgt = [a * b for a in wy for b in wx]
        for (key, ok), w in zip(cells(px, py, oid), wgt, strict=True):
            dr.scatter_reduce(dr.ReduceOp.Add, acc, w, key, live & ~mine & ok & (w > 0))
        return step + 1, [s + dr.select(mine, w, 0.0) for s, w in zip(sums, wgt, strict=True)]

    _, sums = dr.while_loop((step, sums), cond, body, labels=("step", "sums"))
    for (key, ok), s in zip(cells(mx, my, major), sums, strict=True):
        dr.scatter_reduce(dr.ReduceOp.Add, acc, s, key, ok & (s > 0))
    dr.eval(acc)


def ranked_layers(
    pixel: np.ndarray,
    col: np.ndarray,
    share: np.ndarray,
    id_values: np.ndarray,
    layer: str,
    width: int,
    height: int,
    levels: int,
) -> dict[str, np.ndarray]:
    """The ``{layer}00`` ... RGBA channels from a pixel's shares of each id, given as the
    nonzero cells ``(pixel, col, share)`` (column 0 = background, not stored; column ``c`` is
    ``id_values[c - 1]``): ranks by decreasing coverage, ties by column; empty ranks hold id
    0, coverage 0."""
    fg = col > 0
    pixel, col, share = pixel[fg], col[fg], share[fg]
    order = np.lexsort((col, -share, pixel))
    pixel, col, share = pixel[order], col[order], share[order]
    head = np.flatnonzero(np.append(True, pixel[1:] != pixel[:-1]))
    rank = np.arange(len(pixel)) - np.repeat(head, np.diff(np.append(head, len(pixel))))
    ranks = 2 * math.ceil(levels / 2)
    keep = rank < min(levels, ranks)
    ids = np.zeros((ranks, width * height), np.float32)
    cov = np.zeros((ranks, width * height), np.float32)
    ids[rank[keep], pixel[keep]] = id_values[col[keep] - 1]
    cov[rank[keep], pixel[keep]] = share[keep]
    out: dict[str, np.ndarray] = {}
    for r in range(ranks):
        name = f"{layer}{r // 2:02d}"
        chans = ("R", "G") if r % 2 == 0 else ("B", "A")
        out[f"{name}.{chans[0]}"] = ids[r].reshape(height, width)
        out[f"{name}.{chans[1]}"] = cov[r].reshape(height, width)
    return out


def cryptomatte(
    scene: mi.Scene,
    sensor: int | mi.Sensor = 0,
    spp: int | None = None,
    seed: int = 0,
    levels: int = DEFAULT_LEVELS,
) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """``CryptoObject`` and ``CryptoMaterial`` layers of a loaded scene, and their metadata.

    ``spp`` defaults to the sensor's sample count; ``levels`` is the number of ranks kept per
    pixel (rounded up to even: two per RGBA layer).

    **Memory.** The coverage of a band of rows is accumulated densely (its pixels x names, at
    most :data:`BAND_CELLS` cells, a row at least), from the samples of its rows and of the
    rows the filter reaches from beyond it, cast in passes of at most
    :data:`SAMPLES_PER_PASS`; only its nonzero cells are kept. A film whose table fits one
    band is one band (no samples cast twice); in a film of several bands the samples of the
    rows along a band's edge are drawn once for each of the two bands (other random numbers,
    the same estimator).
    """
    if not isinstance(levels, int) or isinstance(levels, bool) or levels < 1:
        raise ParameterError(f"cryptomatte: levels = {levels!r}: must be a positive integer")
    sensor = sensor_of(scene, sensor)
    spp = int(spp) if spp else int(sensor.sampler().sample_count())
    if spp < 1:
        raise ParameterError(f"cryptomatte: spp = {spp!r}: must be a positive integer")
    if not dr.is_jit_v(mi.Float):
        raise ParameterError(
            f"cryptomatte needs a JIT variant (llvm_*, cuda_*), not {mi.variant()}"
        )
    w, h = (int(v) for v in sensor.film().crop_size())
    table = object_table(scene)
    rfilter = sensor.film().rfilter()
    n_obj = len(table.names)
    check_cells(w, 1, n_obj)  # a band holds one row at least
    band = max(1, min(h, BAND_CELLS // (w * (n_obj + 1))))
    reach = _reach(rfilter) if band < h else 0
    cells, p = [], 0
    for r0 in range(0, h, band):
        r1 = min(h, r0 + band)
        s0, s1 = max(0, r0 - reach), min(h, r1 + reach)  # the rows whose samples reach it
        acc = dr.zeros(mi.Float, (r1 - r0) * w * (n_obj + 1))
        # In passes of at most SAMPLES_PER_PASS samples (k per pixel each), so the samples'
        # rays and hits never take more memory than a pass's: pass 0 keeps ``seed``, so a
        # render that fits one pass and one band is the same as one cast of every sample.
        k = max(1, min(spp, SAMPLES_PER_PASS // (w * (s1 - s0))))
        for start in range(0, spp, k):
            n = min(k, spp - start)
            pass_seed = (seed + p * _PASS_SEED_STEP) % 2**32
            xs, ys, obj = _samples(scene, sensor, table, n, pass_seed, (s0, s1))
            _accumulate(acc, xs, ys, obj, n_obj, w, r1 - r0, rfilter, r0, group=n)
            del xs, ys, obj
            p += 1
        cells.append(_shares(acc, r0 * w, (r1 - r0) * w, n_obj))
        del acc
        dr.flush_malloc_cache()  # Dr.Jit keeps freed buffers for reuse: give the band's back
    pixel, col, share = (np.concatenate(c) for c in zip(*cells, strict=True))
    obj_names = [table.names[k] for k in range(1, n_obj + 1)]
    obj_ids = np.array([name_id(n) for n in obj_names], np.float32)
    layers = ranked_layers(pixel, col, share, obj_ids, OBJECT, w, h, levels)
    # Materials: the objects' shares summed per BSDF name (one shared BSDF, one matte).
    mats = material_names(table)
    mat_names = sorted(set(mats.values()))
    to_mat = np.zeros(n_obj + 1, np.int64)
    for oid, name in mats.items():
        to_mat[oid] = 1 + mat_names.index(name)
    key, inverse = np.unique(pixel * (len(mat_names) + 1) + to_mat[col], return_inverse=True)
    mat_pixel, mat_col = np.divmod(key, len(mat_names) + 1)
    mat_share = np.bincount(inverse.ravel(), share, minlength=len(key))
    mat_ids = np.array([name_id(n) for n in mat_names], np.float32)
    layers.update(ranked_layers(mat_pixel, mat_col, mat_share, mat_ids, MATERIAL, w, h, levels))
    meta = {**metadata(OBJECT, obj_names), **metadata(MATERIAL, mat_names)}
    meta["mi_npr/cryptomatte"] = json.dumps({"spp": spp, "seed": seed, "levels": levels})
    return layers, meta


def add_cryptomatte(
    gb: GBuffer,
    scene: mi.Scene,
    sensor: int | mi.Sensor = 0,
    spp: int | None = None,
    seed: int = 0,
    levels: int = DEFAULT_LEVELS,
) -> GBuffer:
    """``gb`` with the Cryptomatte layers of ``scene`` (rendered as ``gb`` was) and metadata."""
    layers, meta = cryptomatte(scene, sensor, spp, seed, levels)
    if (gb.height, gb.width) != next(iter(layers.values())).shape:
        raise ParameterError("cryptomatte: the GBuffer and the scene's film differ in size")
    return gb.with_layers(layers).with_metadata(**meta)


def render(
    scene: str | os.PathLike[str] | mi.Scene,
    *,
    sensor: int = 0,
    spp: int | None = None,
    seed: int = 0,
    levels: int = DEFAULT_LEVELS,
    defines: Mapping[str, Any] | None = None,
    **more: Any,
) -> GBuffer:
    """:func:`mi_npr.render` plus the Cryptomatte layers (what ``mi-npr render --cryptomatte``
    writes); the arguments are :func:`mi_npr.render`'s. A scene whose integrator already has
    ``cryptomatte`` on gets its layers once."""

    session = SceneSession.open(scene, sensor=sensor, spp=spp, defines=merge_defines(defines, more))
    integrator = session.scene.integrator()
    if hasattr(integrator, "npr_gbuffer"):
        gb = integrator.npr_gbuffer(session, spp=session.spp, seed=seed)
    else:
        gb = render_gbuffer(session, beauty=integrator, spp=session.spp, seed=seed)
    if has_cryptomatte(gb):
        return gb
    return add_cryptomatte(gb, session.scene, session.sensor, session.spp, seed, levels)


def has_cryptomatte(gb: GBuffer | Mapping[str, Any]) -> bool:
    names = gb.names if isinstance(gb, GBuffer) else tuple(gb)
    return any(n.startswith((OBJECT, MATERIAL)) for n in names)


def aov_names(levels: int = DEFAULT_LEVELS) -> list[str]:
    """The Cryptomatte channels in ``mi.render``'s order (after an integrator's own)."""
    out = []
    for layer in (OBJECT, MATERIAL):
        for i in range(math.ceil(levels / 2)):
            out += [f"{layer}{i:02d}.{c}" for c in "RGBA"]
    return out


__all__ = [
    "DEFAULT_LEVELS",
    "MATERIAL",
    "OBJECT",
    "add_cryptomatte",
    "aov_names",
    "coverage",
    "cryptomatte",
    "has_cryptomatte",
    "id_bits",
    "layer_key",
    "manifest",
    "material_names",
    "metadata",
    "murmurhash3_32",
    "name_id",
    "render",
]
