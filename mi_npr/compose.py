"""Compositing lines and overlays onto the beauty image (plain numpy, (H, W[, 3]) arrays).

Integrators that draw on the beauty (``npr_lines``, ``npr_contours``, ...) keep the untouched
beauty in the ``beauty.R beauty.G beauty.B`` layers (:data:`mi_npr.layers.RAW_RGB`), so a
compositing application can redo the mix, and write the composited image into ``R G B``.
"""

from __future__ import annotations

from collections.abc import Sequence

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
    a = np.clip(np.nan_to_num(a, nan=0.0), 0.0, 1.0)[..., None]
    return rgb * (1.0 - a) + c * a


def with_overlay(gb: GBuffer, alpha: np.ndarray, color: Sequence[float]) -> GBuffer:
    """``gb`` with ``color`` composited onto R G B; the first call keeps the raw beauty."""
    raw = {} if L.RAW_RGB[0] in gb else dict(zip(L.RAW_RGB, (gb[c] for c in L.RGB), strict=True))
    out = over(gb.beauty, alpha, color)
    return gb.with_layers({**raw, **{c: out[..., i] for i, c in enumerate(L.RGB)}})


def with_overlays(gb: GBuffer, overlays: Sequence[tuple[np.ndarray, Sequence[float]]]) -> GBuffer:
    """``gb`` with several ``(alpha, color)`` overlays composited in order: the same image as
    chained :func:`with_overlay` calls, built once. Binary masks (alpha only 0 or 1, as edge
    layers are) are drawn by assignment, channel by channel, several times faster."""
    raw = {} if L.RAW_RGB[0] in gb else dict(zip(L.RAW_RGB, (gb[c] for c in L.RGB), strict=True))
    planes = [gb[c].copy() for c in L.RGB]
    for alpha, color in overlays:
        a = np.asarray(alpha)
        c = np.asarray(color, dtype=np.float32).reshape(-1)
        m = a == 1
        if a.shape == gb.shape and c.size == 3 and m.sum() + (a == 0).sum() == a.size:
            for plane, v in zip(planes, c, strict=True):
                plane[m] = v
        else:
            out = over(np.stack(planes, axis=-1), a, color)
            planes = [np.ascontiguousarray(out[..., i]) for i in range(3)]
    return gb.with_layers({**raw, **dict(zip(L.RGB, planes, strict=True))})


def raw_beauty(gb: GBuffer) -> np.ndarray:
    """The beauty before any overlay: ``beauty.R/G/B`` if present, else ``R G B``."""
    return gb.stack(L.RAW_RGB) if L.RAW_RGB[0] in gb else gb.beauty
