"""Compositing lines and overlays onto the beauty image.

:func:`with_overlay` and :func:`with_overlays` work on a :class:`~mi_npr.gbuffer.GBuffer`'s
tensors in Dr.Jit (no host round trip; gradients kept on AD variants); :func:`over` is the same
rule on plain numpy (H, W, 3) arrays. The rule, per channel: ``rgb (1 - a) + color a`` with the
coverage ``a`` clipped to [0, 1] (NaN counts as 0); where ``a`` is exactly 0 or 1 the result is
exactly the beauty or the colour (an infinite beauty value does not turn into NaN).

Integrators that draw on the beauty (``npr_lines``, ``npr_contours``, ...) keep the untouched
beauty in the ``beauty.R beauty.G beauty.B`` layers (:data:`mi_npr.layers.RAW_RGB`), so a
compositing application can redo the mix, and write the composited image into ``R G B``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from . import layers as L
from .errors import ParameterError
from .gbuffer import GBuffer


def over(rgb: np.ndarray, alpha: np.ndarray, color: Sequence[float]) -> np.ndarray:
    """``color`` laid over ``rgb`` with per-pixel coverage ``alpha`` in [0, 1] (NaN counts as 0).

    ``rgb`` is (H, W, 3) linear RGB, ``alpha`` (H, W); returns a new float32 (H, W, 3) array.
    """
    rgb = np.asarray(rgb, dtype=np.float32)
    a = np.asarray(alpha, dtype=np.float32)
    if rgb.ndim != 3 or rgb.shape[-1] != 3 or a.shape != rgb.shape[:2]:
        raise ParameterError(f"over: rgb {rgb.shape} and alpha {a.shape} do not match")
    c = np.asarray(color, dtype=np.float32).reshape(-1)
    if c.size != 3:
        raise ParameterError(f"over: color {tuple(color)!r} is not an RGB triple")
    a = np.clip(np.nan_to_num(a, nan=0.0), 0.0, 1.0)
    keep = 1.0 - a
    out = np.empty(rgb.shape, np.float32)
    for i in range(3):  # a channel at a time: numpy is slow on an innermost axis of 3
        np.add(rgb[..., i] * keep, c[i] * a, out=out[..., i])
    return out


def _coverage(alpha: Any, shape: tuple[int, int]) -> Any:
    """``alpha`` (a tensor or an array of ``shape``) as a flat Dr.Jit Float in [0, 1]."""
    if dr.is_tensor_v(alpha) and dr.is_jit_v(alpha):
        got = tuple(int(v) for v in alpha.shape)
        a = mi.Float(alpha.array)
    else:
        arr = np.asarray(alpha, dtype=np.float32)
        got = arr.shape
        a = mi.Float(np.ascontiguousarray(arr).reshape(-1))
    if got != shape:
        raise ParameterError(f"overlay: alpha {got} does not match the image {shape}")
    return dr.clip(dr.select(dr.isnan(a), 0.0, a), 0.0, 1.0)


def _rgb(color: Sequence[float]) -> list[float]:
    c = np.asarray(color, dtype=np.float32).reshape(-1)
    if c.size != 3:
        raise ParameterError(f"overlay: color {tuple(color)!r} is not an RGB triple")
    return [float(v) for v in c]


def with_overlays(gb: GBuffer, overlays: Sequence[tuple[Any, Sequence[float]]]) -> GBuffer:
    """``gb`` with several ``(alpha, color)`` overlays composited onto R G B in order, in one
    Dr.Jit kernel per channel; the first overlay of a G-buffer keeps the raw beauty in
    ``beauty.R/G/B``."""
    raw = {} if L.RAW_RGB[0] in gb else dict(zip(L.RAW_RGB, (gb[c] for c in L.RGB), strict=True))
    planes = [mi.Float(gb[c].array) for c in L.RGB]
    for alpha, color in overlays:
        a, c = _coverage(alpha, gb.shape), _rgb(color)
        planes = [
            dr.select(a == 1.0, v, dr.select(a == 0.0, p, p * (1.0 - a) + v * a))
            for p, v in zip(planes, c, strict=True)
        ]
    dr.eval(*planes)
    out = {name: mi.TensorXf(p, shape=gb.shape) for name, p in zip(L.RGB, planes, strict=True)}
    return gb.with_layers({**raw, **out})


def with_overlay(gb: GBuffer, alpha: Any, color: Sequence[float]) -> GBuffer:
    """``gb`` with ``color`` composited onto R G B; the first call keeps the raw beauty."""
    return with_overlays(gb, [(alpha, color)])


def over_raw(gb: GBuffer, alpha: Any, ink: Any) -> GBuffer:
    """``gb`` with a premultiplied colour image laid over its raw beauty, ``R G B = raw (1 -
    alpha) + ink``, in Dr.Jit (gradients kept through the beauty); the raw beauty kept in
    ``beauty.R/G/B``. ``alpha``: (H, W) coverage, ``ink``: (H, W, 3) premultiplied linear RGB."""
    raw = raw_beauty_layers(gb)
    a = _coverage(alpha, gb.shape)
    ink = np.asarray(ink, np.float32)
    if ink.shape != (*gb.shape, 3):
        raise ParameterError(f"over_raw: ink {ink.shape} does not match the image {gb.shape}")
    out = {n: raw[c] for n, c in zip(L.RAW_RGB, L.RGB, strict=True)}
    for i, c in enumerate(L.RGB):
        v = mi.Float(raw[c].array) * (1.0 - a) + mi.Float(np.ascontiguousarray(ink[..., i]).ravel())
        out[c] = mi.TensorXf(v, shape=gb.shape)
    return gb.with_layers(out)


def raw_beauty_layers(gb: GBuffer) -> dict[str, Any]:
    """The beauty before any overlay as ``R G B`` layers, Dr.Jit tensors with their AD graph:
    ``beauty.R/G/B`` if present, else ``R G B``."""
    src = L.RAW_RGB if L.RAW_RGB[0] in gb else L.RGB
    return {c: gb[s] for c, s in zip(L.RGB, src, strict=True)}


def raw_beauty(gb: GBuffer) -> np.ndarray:
    """The beauty before any overlay: ``beauty.R/G/B`` if present, else ``R G B``."""
    return gb.stack(L.RAW_RGB) if L.RAW_RGB[0] in gb else gb.beauty


#: Black ink on white paper (linear RGB).
INK, PAPER = (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)


def lines_on_paper(
    gb: GBuffer, line_color: Sequence[float] = INK, paper: Sequence[float] = PAPER
) -> np.ndarray:
    """The ``lines`` layer of ``gb`` as ``line_color`` on ``paper``: (H, W, 3) linear RGB, the
    picture of ``<stem>_lines.png``."""
    if L.LINES not in gb:
        raise ParameterError(f"the G-buffer has no {L.LINES!r} layer (render with npr_lines)")
    h, w = gb.shape
    sheet = np.broadcast_to(np.asarray(paper, np.float32).reshape(1, 1, 3), (h, w, 3))
    return over(sheet, gb.numpy(L.LINES), line_color)
