"""Anti-aliased lines: the line chain on a supersampled G-buffer, box-filtered to the
film's resolution.

The G-buffer of :mod:`mi_npr.render` has one exact ray per pixel centre, so every line is a row
of whole pixels, jagged wherever it is not axis-aligned. With ``n > 1`` the G-buffer is traced
again with ``n x n`` rays per pixel, at the sub-pixel centres ``x + (i + 0.5) / n`` (the centres
of the pixels of a film ``n`` times larger), the chain of :func:`mi_npr.kernels.lines` runs on
that ``(n H, n W)`` G-buffer with lines :func:`aa_width` sub-pixels wide, and each film pixel
gets the mean of its ``n x n`` block: the gray level is the share of the pixel's area that the
line covers, so lines come out smooth at the film's resolution.

**Full ink on every line** (:func:`aa_width`). A ``w``-px line becomes a band of
``W = max(w n, 2 n - 1)`` sub-pixels: at least ``2 - 1/n`` film pixels wide. ``2 n - 1``
consecutive sub-pixels always hold one film pixel's ``n`` whole, so an axis-aligned line covers
at least one film pixel fully wherever its sub-pixel position falls: its darkest pixel is full
ink, as at ``n = 1``, never two light-gray halves (a band of exactly ``n`` sub-pixels at a third
of a pixel gives 0.67 + 0.33). Across an axis-aligned line the ink adds up to ``W / n`` px
(``5/3`` for ``w = 1``, ``n = 3``) whatever the position, so a moving line does not pulse, and a
silhouette against the background carries the same ink as a crease. Lines already that wide
(``w >= 2 - 1/n``) keep ``w n``; a line thinner than 1 px is the 1-px band lightened by ``w``,
as :func:`mi_npr.kernels.widen_lines` lightens it at ``n = 1``. At ``n = 1``, ``W = w``.

How this extends the thesis (section 5.1). Eq. 5.1 already gives gray levels to small depth
steps; supersampling carries its contours to sub-pixel positions: a contour that runs through a
film pixel at a fraction of its width inks that fraction. The other stages run at the
supersampled resolution, in sub-pixels:

- eq. 5.2 (isolated-pixel removal) removes contour fragments shorter than 3 *sub-pixels*, so
  fragments of a film pixel survive that would vanish at ``n = 1``; fragments shorter than the
  film pixel then enter as faint gray, not as a black dot;
- the selective dilation (eqs. 5.3-5.4) fills holes of ``dilation_size`` sub-pixels, i.e.
  ``dilation_size / n`` film pixels: it fills the same geometric holes as at ``n = 1`` only
  up to that size; raise ``dilation_size`` with ``n`` to fill wider ones;
- ``max_density`` measures ink over a 9x9 window of sub-pixels; ``bright_fade`` is applied after
  the box filter, from the film-resolution beauty.

``antialiased_lines(..., n)`` equals ``box_filter(lines(G, line_width=aa_width(w, n)), n)``
(times ``w`` below 1 px) with ``G`` the pixel-centre G-buffer of the same camera on a film ``n``
times larger (bit for bit where the sub-pixel positions are exact in float32, e.g. ``n`` a power
of two).
"""

from __future__ import annotations

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
from .kernels.ink import MAX_WIDTH
from .params import check_values
from .raycast import film_size, require_jit
from .render import grid_channels
from .scene import object_table
from .session import RENDER_LOCK

#: Most rays per pixel side: 8 x 8 = 64 rays per pixel.
MAX_AA = 8


def aa_factor(v: Any) -> str | None:
    """The rule for ``line_aa``: an integer in [1, MAX_AA] (rays per pixel side)."""
    ok = isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_AA
    return None if ok else f"must be an integer in [1, {MAX_AA}] (rays per pixel side)"


def aa_width(width: float, n: int) -> float:
    """The width in sub-pixels of a ``width``-px line on the ``n``-times supersampled G-buffer:
    ``max(width n, 2 n - 1)``, the narrowest band that always covers one film pixel whole
    (module docstring); ``2 n - 1`` below 1 px, where the ink is then scaled by ``width``.

    >>> aa_width(1.0, 3), aa_width(2.0, 3), aa_width(1.0, 1), aa_width(0.5, 4)
    (5.0, 6.0, 1.0, 7.0)
    """
    return float(width) * n if width * n >= 2 * n - 1 else 2.0 * n - 1.0


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


def supersampled_gbuffer(scene: mi.Scene, sensor: mi.Sensor, n: int) -> GBuffer:
    """The G-buffer layers ``Z P N object_id prim_id`` of ``n x n`` rays per pixel, laid out as
    an ``(n H, n W)`` image (the pixel-centre G-buffer of a film ``n`` times larger, seams closed
    as in :mod:`mi_npr.render`)."""
    require_jit("line_aa")
    w, h = film_size(sensor)
    W, H = w * n, h * n
    with RENDER_LOCK:
        table = object_table(scene)
        # (j + 0.5) / n film pixels: the centre of sub-pixel j of the n-times-larger film.
        out = grid_channels(scene, sensor, table, shade=False, n=n)
    TF, TU = mi.TensorXf, mi.TensorXu
    layers = {
        k: (TU if isinstance(out[k], mi.UInt32) else TF)(out[k], shape=(H, W))
        for k in L.GBUFFER_AOVS
    }
    return GBuffer(layers, table.names, projection_of(sensor))


def box_filter(image: Any, n: int) -> Any:
    """The mean of every ``n x n`` block of an ``(n H, n W)`` image (a tensor or an array): an
    ``(H, W)`` float32 tensor, computed in Dr.Jit (each pixel's block gathered contiguously,
    then one block sum)."""
    if dr.is_tensor_v(image) and dr.is_jit_v(image):
        shape, v = tuple(int(s) for s in image.shape), mi.Float(image.array)
    else:
        a = np.asarray(image, dtype=np.float32)
        shape, v = a.shape, mi.Float(np.ascontiguousarray(a).reshape(-1))
    if len(shape) != 2 or shape[0] % n or shape[1] % n:
        raise ParameterError(f"box_filter: shape {shape} is not a multiple of {n}")
    h, w = shape[0] // n, shape[1] // n
    k = dr.arange(mi.UInt32, h * w * n * n)
    p, j = k // (n * n), k % (n * n)  # output pixel, sample within its block
    src = ((p // w) * n + j // n) * shape[1] + (p % w) * n + j % n
    mean = dr.block_sum(dr.gather(mi.Float, v, src), n * n) * (1.0 / (n * n))
    return mi.TensorXf(mean, shape=(h, w))


def _mapped(gb: GBuffer, ids: Any) -> GBuffer:
    """``gb`` with its ``object_id`` layer in the ids of an
    :class:`~mi_npr.contours.idmode.IdMap` (id mode and object selection)."""
    if ids is None or ids.identity:
        return gb
    return gb.with_layers({L.OBJECT_ID: ids.apply(gb[L.OBJECT_ID], gb[L.PRIM_ID])})


def antialiased_lines(
    scene: mi.Scene, sensor: mi.Sensor, gb: GBuffer, n: int, ids: Any = None, **params: Any
) -> Any:
    """The ``lines`` layer (an (H, W) tensor) with ``n x n`` rays per pixel (module
    docstring); ``n = 1`` is :func:`mi_npr.kernels.lines` on ``gb`` itself. ``gb`` is the
    film-resolution G-buffer (for ``bright_fade``); ``params`` are those of
    :data:`~mi_npr.kernels.LINES_PARAMS`. ``ids`` (an :class:`~mi_npr.contours.idmode.IdMap`)
    replaces the object ids that ID edges and creases read: another id mode, unselected
    objects as background."""
    problem = aa_factor(n)
    if problem:
        raise ParameterError(f"line_aa = {n!r}: {problem}")
    check_values("lines", LINES_PARAMS, params)
    if n == 1:
        return lines(_mapped(gb, ids), **params)
    width = float(params.get("line_width", 1.0))
    check_aa_width(width, n)
    big = _mapped(supersampled_gbuffer(scene, sensor, n), ids)
    if params.get("leaf_edges"):
        big = big.with_layers({L.LEAF_ID: leaf_id_layer(scene, big)})
    level = float(params.get("bright_fade", 0.0))
    sub = {**params, "line_width": aa_width(width, n), "bright_fade": 0.0}
    ink = box_filter(lines(big, **sub), n)
    if width < 1.0:  # thinner than a pixel: the 1-px line, lightened (module docstring)
        ink = mi.TensorXf(ink.array * width, shape=ink.shape)
    if level > 0:
        ink = mi.TensorXf(ink.array * fade(gb, Grid(gb.shape, ink.array), level), shape=gb.shape)
    dr.eval(ink)
    return ink
