"""Anti-aliased lines: the line chain on a supersampled G-buffer, box-filtered to the
film's resolution and normalised by each line's coverage peak.

The G-buffer of :mod:`mi_npr.render` has one exact ray per pixel centre, so every line is a row
of whole pixels, jagged wherever it is not axis-aligned. With ``n > 1`` the G-buffer is traced
again with ``n x n`` rays per pixel, at the sub-pixel centres ``x + (i + 0.5) / n`` (the centres
of the pixels of a film ``n`` times larger), the chain of :func:`mi_npr.kernels.lines` runs on
that ``(n H, n W)`` G-buffer with ``line_width`` scaled by ``n`` (:func:`aa_width`), and each
film pixel gets the mean of its ``n x n`` block, ``b``: the share of the pixel's area that the
line covers, so lines come out smooth at the film's resolution and keep their width in film
pixels.

**Full ink on every line** (:func:`full_ink_filter`). The box filter alone splits a line that
falls between pixel centres into two light grays: a 1-px band of ``n`` sub-pixels at a third of
a pixel gives 0.67 + 0.33, lighter than the same line at ``n = 1``. So each pixel's ``b`` is
divided by the line's own coverage peak ``m`` and multiplied by its gray ``g``::

    ink = min(b * g / m, top)        (0 where m = 0)

``top`` is the darkest sub-pixel of the pixel's own block; ``m`` and ``g`` are the largest ``b``
and ``top`` of the three pixels ``p - d, p, p + d`` of the cross-section through the pixel,
``d`` its row or its column, whichever ``b`` rises more along (from its least to its largest
value; the row on a tie). For a band of uniform gray ``g`` (eq. 5.1's gray level), ``b / g`` is
the share of the pixel's sub-pixels that the line inks, so the best-covered pixel across the line
gets exactly ``g`` (full ink for a black line, ``g`` for a gray one) and the others keep their
coverage relative to it: a 1-px line at a third of a pixel is 1 + 0.5 (``n = 3``), at a pixel's
edge 1 + 0, silhouettes and creases alike. Across an axis-aligned 1-px line the ink is
``1 + min(k, n - k) / max(k, n - k)`` px for a band starting ``k`` sub-pixels into a pixel
(odd ``n``; 1 to 1.5 px at ``n = 3``): its ink width (pixels above 0.5) stays about 1 px, and a
moving line keeps its darkest pixel. Ambiguities resolved:

- *coverage in ink, not a binary mask*: ``line_width`` widens with a soft disc
  (:func:`~mi_npr.kernels.widen_lines`), which at even ``n`` gives the band half-ink sides (a
  1-px band at ``n = 2`` is 0.5, 1, 0.5 sub-pixels). Counted as whole sub-pixels they would
  leave the darkest pixel at 0.75 (``n = 2``) or 0.875 (``n = 4``); counted at their ink, 1;
- *a row or a column, not the 3 x 3 square*: a crease found on the supersampled G-buffer steps
  one sub-pixel from row to row, so successive film rows of one straight line peak at different
  ``b`` (0.62, 0.67, 1); a square window (or a diagonal) lets a better-aligned neighbouring row
  set ``m`` and leaves a row's darkest pixel at 0.7 to 0.93. Across a line ``b`` rises from 0 to
  its peak, along it only by the staircase, so the larger rise picks the cross-section; a 45
  degree line is crossed by both;
- *three pixels, whatever the width*: an axis-aligned band covers the pixels inside it whole
  and only the two at its ends in part, and each of those lies next to the best-covered one
  (for ``w >= 2 - 1/n`` a fully covered one: such lines keep ``b``). A window of
  ``ceil(w) + 2`` pixels would find nothing more of the line, only its neighbours;
- *the clamp to* ``top`` keeps a pixel no darker than its darkest sub-pixel where ``g`` comes
  from a darker line beside it (a gray crease next to a black silhouette stays gray);
- *below 1 px* the line is the 1-px line lightened by ``w``, as
  :func:`~mi_npr.kernels.widen_lines` lightens it at ``n = 1`` (a ``w n``-sub-pixel band,
  normalised, would be as dark as a 1-px line);
- ``n = 1`` is the chain itself (the filter is then the identity).

How this extends the thesis (section 5.1). Eq. 5.1 already gives gray levels to small depth
steps; supersampling carries its contours to sub-pixel positions: a contour that runs through a
film pixel at a fraction of its width inks that fraction of its best-covered pixel's ink. The
other stages run at the supersampled resolution, in sub-pixels:

- eq. 5.2 (isolated-pixel removal) removes contour fragments shorter than 3 *sub-pixels*, so
  fragments of a film pixel survive that would vanish at ``n = 1``; normalised by their own
  peak, they enter as a pixel of their line's ink;
- the selective dilation (eqs. 5.3-5.4) fills holes of ``dilation_size`` sub-pixels, i.e.
  ``dilation_size / n`` film pixels: it fills the same geometric holes as at ``n = 1`` only
  up to that size; raise ``dilation_size`` with ``n`` to fill wider ones;
- ``max_density`` measures ink over a 9x9 window of sub-pixels; ``bright_fade`` is applied after
  the filter, from the film-resolution beauty;
- the depths are normalised over the film's range (``near`` and ``far`` unset), not the
  sub-pixels': the gray levels of eq. 5.1 do not change with ``n``.

``antialiased_lines(..., n)`` equals ``full_ink_filter(lines(G, line_width=aa_width(w, n),
depth_range=R), n)`` (times ``w`` below 1 px) with ``G`` the pixel-centre G-buffer of the same
camera on a film ``n`` times larger and ``R`` the film's own depth range (its pixel centres', as
at ``n = 1``) (bit for bit where the sub-pixel positions are exact in float32, e.g. ``n`` a power
of two).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from . import layers as L
from .camera import projection_of
from .errors import ParameterError
from .foliage.leaves import leaf_id_layer
from .gbuffer import GBuffer
from .kernels import LINES_PARAMS, lines
from .kernels._stencil import Grid
from .kernels.chain import fade
from .kernels.depth_lines import finite_range
from .kernels.ink import DENSITY_WINDOW, MAX_WIDTH
from .params import check_values
from .raycast import film_size, require_jit
from .render import grid_channels
from .scene import ObjectTable, object_table
from .session import RENDER_LOCK

#: Most rays per pixel side: 8 x 8 = 64 rays per pixel.
MAX_AA = 8

#: The directions (dy, dx) of a line's cross-section through a pixel, its row and its column:
#: the 3 pixels ``p - d, p, p + d`` (:func:`full_ink_filter`).
ACROSS = ((0, 1), (1, 0))

#: Most sub-pixels of the supersampled film traced and drawn at once; a larger film is done in
#: strips of rows (:func:`antialiased_lines`). About 1.5 M, some 100 bytes each: a 384 x 384
#: film at ``n = 3`` is drawn whole, a 4K one (75 M sub-pixels) in some 55 strips, holding less
#: than its own G-buffer pass does.
STRIP_SAMPLES = 3 << 19


def aa_factor(v: Any) -> str | None:
    """The rule for ``line_aa``: an integer in [1, MAX_AA] (rays per pixel side)."""
    ok = isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_AA
    return None if ok else f"must be an integer in [1, {MAX_AA}] (rays per pixel side)"


def aa_width(width: float, n: int) -> float:
    """The width in sub-pixels of a ``width``-px line on the ``n``-times supersampled G-buffer:
    ``width n``, and ``n`` (the 1-px line, lightened by ``width`` after the filter) below 1 px
    (module docstring).

    >>> aa_width(1.0, 3), aa_width(1.5, 4), aa_width(1.0, 1), aa_width(0.5, 4)
    (3.0, 6.0, 1.0, 4.0)
    """
    return float(max(width, 1.0)) * n


def check_aa_width(width: float, n: int, who: str = "") -> None:
    """The supersampled line (:func:`aa_width`) is at most
    :data:`~mi_npr.kernels.ink.MAX_WIDTH` sub-pixels wide."""
    sub = aa_width(width, n)
    if sub > MAX_WIDTH:
        prefix = f"{who}: " if who else ""
        raise ParameterError(
            f"{prefix}line_width = {width:g} with line_aa = {n}: {sub:g} sub-pixels wide, "
            f"more than {MAX_WIDTH:g}"
        )


def supersampled_gbuffer(
    scene: mi.Scene,
    sensor: mi.Sensor,
    n: int,
    rows: tuple[int, int] | None = None,
    table: ObjectTable | None = None,
) -> GBuffer:
    """The G-buffer layers ``Z P N object_id prim_id`` of ``n x n`` rays per pixel, laid out as
    an ``(n H, n W)`` image (the pixel-centre G-buffer of a film ``n`` times larger, seams closed
    as in :mod:`mi_npr.render`); ``rows = (r0, r1)``: the film's rows ``r0 .. r1 - 1`` only, an
    ``(n (r1 - r0), n W)`` strip (seams closed against the strip alone). ``table``: the scene's
    object table (built when not given)."""
    require_jit("line_aa")
    w, h = film_size(sensor)
    r0, r1 = (0, h) if rows is None else rows
    W, H = w * n, (r1 - r0) * n
    with RENDER_LOCK:
        table = table if table is not None else object_table(scene)
        # (j + 0.5) / n film pixels: the centre of sub-pixel j of the n-times-larger film.
        out = grid_channels(scene, sensor, table, shade=False, n=n, rows=(r0 * n, r1 * n))
    TF, TU = mi.TensorXf, mi.TensorXu
    layers = {
        k: (TU if isinstance(out[k], mi.UInt32) else TF)(out[k], shape=(H, W))
        for k in L.GBUFFER_AOVS
    }
    return GBuffer(layers, table.names, projection_of(sensor))


def _blocks(image: Any, n: int, who: str) -> tuple[Any, int, int]:
    """The values of an ``(n H, n W)`` image (a tensor or an array) as a flat ``Float``, each
    film pixel's ``n x n`` block contiguous, and ``H, W``."""
    if dr.is_tensor_v(image) and dr.is_jit_v(image):
        shape, v = tuple(int(s) for s in image.shape), mi.Float(image.array)
    else:
        a = np.asarray(image, dtype=np.float32)
        shape, v = a.shape, mi.Float(np.ascontiguousarray(a).reshape(-1))
    if len(shape) != 2 or shape[0] % n or shape[1] % n:
        raise ParameterError(f"{who}: shape {shape} is not a multiple of {n}")
    h, w = shape[0] // n, shape[1] // n
    k = dr.arange(mi.UInt32, h * w * n * n)
    p, j = k // (n * n), k % (n * n)  # output pixel, sample within its block
    src = ((p // w) * n + j // n) * shape[1] + (p % w) * n + j % n
    return dr.gather(mi.Float, v, src), h, w


def box_filter(image: Any, n: int) -> Any:
    """The mean of every ``n x n`` block of an ``(n H, n W)`` image (a tensor or an array): an
    ``(H, W)`` float32 tensor, computed in Dr.Jit (each pixel's block gathered contiguously,
    then one block sum)."""
    v, h, w = _blocks(image, n, "box_filter")
    return mi.TensorXf(dr.block_sum(v, n * n) * (1.0 / (n * n)), shape=(h, w))


def full_ink_filter(image: Any, n: int) -> Any:
    """The box filter of an ``(n H, n W)`` line image (a tensor or an array) normalised by each
    line's coverage peak: ``min(b g / m, top)``, 0 where ``m = 0``, with ``b`` the block mean,
    ``top`` the block's largest value, ``m`` and ``g`` the largest ``b`` and ``top`` over the
    pixel's cross-section: the 3 pixels of its row or column around it, whichever ``b`` rises
    more along (module docstring). An ``(H, W)`` float32 tensor, in Dr.Jit (differentiable).

    A 1-px band (3 sub-pixels at ``n = 3``) a third of a pixel into pixel 1:

    >>> a = np.zeros((3, 9), np.float32); a[:, 4:7] = 1
    >>> np.asarray(box_filter(a, 3)).round(2), np.asarray(full_ink_filter(a, 3)).round(2)
    (array([[0.  , 0.67, 0.33]], dtype=float32), array([[0. , 1. , 0.5]], dtype=float32))
    >>> np.asarray(full_ink_filter(0.4 * a, 3)).round(2)  # eq. 5.1's gray survives
    array([[0. , 0.4, 0.2]], dtype=float32)
    """
    v, h, w = _blocks(image, n, "full_ink_filter")
    b = dr.block_sum(v, n * n) * (1.0 / (n * n))
    top = dr.block_reduce(dr.ReduceOp.Max, v, n * n)
    grid = Grid((h, w), b)
    m, g, steepest = b, top, dr.full(mi.Float, -1.0, h * w)
    for dy, dx in ACROSS:
        i, j = grid.index(-dy, -dx), grid.index(dy, dx)  # border pixels repeat
        b0, b1 = dr.gather(mi.Float, b, i), dr.gather(mi.Float, b, j)
        hi = dr.maximum(b, dr.maximum(b0, b1))
        rise = hi - dr.minimum(b, dr.minimum(b0, b1))
        take = rise > steepest
        steepest = dr.select(take, rise, steepest)
        m = dr.select(take, hi, m)
        t = dr.maximum(top, dr.maximum(dr.gather(mi.Float, top, i), dr.gather(mi.Float, top, j)))
        g = dr.select(take, t, g)
    # m = 0 only where b = 0: divide by 1 there so that no NaN reaches a gradient.
    ink = dr.minimum(b * g / dr.select(m > 0, m, 1.0), top)
    return mi.TensorXf(ink, shape=(h, w))


def _mapped(gb: GBuffer, ids: Any) -> GBuffer:
    """``gb`` with its ``object_id`` layer in the ids of an
    :class:`~mi_npr.contours.idmode.IdMap` (id mode and object selection)."""
    if ids is None or ids.identity:
        return gb
    return gb.with_layers({L.OBJECT_ID: ids.apply(gb[L.OBJECT_ID], gb[L.PRIM_ID])})


def chain_reach(params: Mapping[str, Any]) -> int:
    """How far (pixels) the chain of :func:`mi_npr.kernels.lines` with ``params`` reads
    around a pixel, at most: each selective dilation its window's half, eq. 5.1 and eq. 5.2 one
    each (the edges one), each of up to two ``max_density`` thinnings half the density window,
    ``line_width`` its disc's radius. A pixel farther than this from the border of a part of
    the image gets the same line from the part as from the whole image.

    >>> chain_reach({}), chain_reach({"dilation_iterations": 2, "line_width": 4.0})
    (3, 6)
    """
    p = check_values("lines", LINES_PARAMS, params)
    reach = p["dilation_iterations"] * (p["dilation_size"] // 2) + 2
    if p["max_density"] < 1.0:
        reach += 2 * (DENSITY_WINDOW // 2)
    return reach + max(math.ceil((p["line_width"] - 1.0) * 0.5), 0)


def strips(h: int, core: int, halo: int) -> list[tuple[int, int, int, int]]:
    """The strips of an ``h``-row film: ``(r0, r1, s0, s1)``, the rows ``r0 .. r1 - 1`` of
    each (``core`` rows, the last fewer) computed on the rows ``s0 .. s1 - 1`` around them,
    ``halo`` more on every side that is not the film's border; every window has the same
    height (``core + 2 halo``, at most ``h``), so that the kernels compile once.

    >>> strips(10, 4, 1)
    [(0, 4, 0, 6), (4, 8, 3, 9), (8, 10, 4, 10)]
    """
    height = min(h, core + 2 * halo)
    out = []
    for r0 in range(0, h, core):
        s0 = min(max(r0 - halo, 0), h - height)
        out.append((r0, min(r0 + core, h), s0, s0 + height))
    return out


def _rows(a: Any, first: int, count: int, width: int) -> Any:
    """Rows ``first .. first + count - 1`` of a flat row-major image ``width`` wide."""
    return dr.gather(type(a), a, dr.arange(mi.UInt32, count * width) + first * width)


def antialiased_lines(
    scene: mi.Scene,
    sensor: mi.Sensor,
    gb: GBuffer,
    n: int,
    ids: Any = None,
    *,
    strip_samples: int = STRIP_SAMPLES,
    **params: Any,
) -> Any:
    """The ``lines`` layer (an (H, W) tensor) with ``n x n`` rays per pixel (module
    docstring); ``n = 1`` is :func:`mi_npr.kernels.lines` on ``gb`` itself. ``gb`` is the
    film-resolution G-buffer (for ``bright_fade``); ``params`` are those of
    :data:`~mi_npr.kernels.LINES_PARAMS`. ``ids`` (an :class:`~mi_npr.contours.idmode.IdMap`)
    replaces the object ids that ID edges and creases read: another id mode, unselected
    objects as background.

    The frame's depth range (what ``near`` and ``far`` default to) is the film's: that of
    ``gb``'s pixel centres, as at ``n = 1``, so supersampling smooths the lines without moving
    eq. 5.1's normalisation (a sub-pixel ray may meet a surface nearer or farther than every
    pixel centre does).

    Memory: where the supersampled film has more than ``strip_samples`` sub-pixels, it is
    traced and drawn in strips of film rows (:func:`strips`), each with a halo of the rows the
    chain reads (:func:`chain_reach`, plus the sub-pixel row whose seams the strip cannot close
    and the film row of :func:`full_ink_filter`'s cross-section): the same lines as the whole
    film at once, at most about ``strip_samples`` sub-pixels held at a time, each traced once."""
    problem = aa_factor(n)
    if problem:
        raise ParameterError(f"line_aa = {n!r}: {problem}")
    if isinstance(strip_samples, bool) or not isinstance(strip_samples, int) or strip_samples < 1:
        raise ParameterError(f"strip_samples = {strip_samples!r}: must be an integer >= 1")
    check_values("lines", LINES_PARAMS, params)
    if n == 1:
        return lines(_mapped(gb, ids), **params)
    width = float(params.get("line_width", 1.0))
    check_aa_width(width, n)
    level = float(params.get("bright_fade", 0.0))
    sub = {**params, "line_width": aa_width(width, n), "bright_fade": 0.0}

    with RENDER_LOCK:
        table = object_table(scene)  # once, not once a strip

    def strip_gbuffer(rows: tuple[int, int] | None) -> GBuffer:
        big = _mapped(supersampled_gbuffer(scene, sensor, n, rows, table), ids)
        if params.get("leaf_edges"):
            big = big.with_layers({L.LEAF_ID: leaf_id_layer(scene, big)})
        return big

    w, h = film_size(sensor)
    # +1 sub-pixel: a strip's outer row, whose seams it cannot close; +1 film row: the
    # cross-section of full_ink_filter.
    halo = math.ceil((chain_reach(sub) + 1) / n) + 1
    core = max(1, strip_samples // (w * n * n) - 2 * halo)
    parts = strips(h, core, halo)
    frame = finite_range(gb[L.Z].array)  # the film's depth range, whatever n (docstring)
    if len(parts) == 1:
        ink = full_ink_filter(lines(strip_gbuffer(None), depth_range=frame, **sub), n)
    else:
        out = dr.zeros(mi.Float, h * w)
        for r0, r1, s0, s1 in parts:
            part = full_ink_filter(lines(strip_gbuffer((s0, s1)), depth_range=frame, **sub), n)
            at = dr.arange(mi.UInt32, (r1 - r0) * w) + r0 * w
            dr.scatter(out, _rows(part.array, r0 - s0, r1 - r0, w), at)
            dr.eval(out)
        ink = mi.TensorXf(out, shape=(h, w))
    if width < 1.0:  # thinner than a pixel: the 1-px line, lightened (module docstring)
        ink = mi.TensorXf(ink.array * width, shape=ink.shape)
    if level > 0:
        ink = mi.TensorXf(ink.array * fade(gb, Grid(gb.shape, ink.array), level), shape=gb.shape)
    dr.eval(ink)
    return ink
