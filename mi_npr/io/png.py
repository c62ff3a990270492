"""PNG output (Pillow): beauty renders and overlays, sRGB-encoded, written atomically."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from ..errors import ParameterError, as_path, shown
from ..params import MAX_RES
from ._atomic import atomic_output

#: zlib level of every PNG mi-npr writes: the fastest one. On renders it makes files about as
#: small as the default level 6 (noise does not compress); flat line drawings come out a few
#: kilobytes larger.
PNG_LEVEL = 1


def save_png(rgb8: np.ndarray, fp: Any) -> None:
    """Encode 8-bit ``rgb8`` ((H, W), (H, W, 3) or (H, W, 4)) as PNG into a file name or
    binary file object."""
    Image.fromarray(rgb8).save(fp, format="PNG", compress_level=PNG_LEVEL)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1) on linear values, clipped to [0, 1]."""
    y = np.array(x, dtype=np.float32)
    np.nan_to_num(y, copy=False, nan=0.0)
    np.clip(y, 0.0, 1.0, out=y)
    return _srgb(y)


def _srgb(y: np.ndarray) -> np.ndarray:
    """:func:`linear_to_srgb` of a float32 array in [0, 1], in place: the same float32
    operations, on the same whole array, with fewer temporaries."""
    low = y <= 0.0031308
    linear = 12.92 * y[low]
    np.power(y, 1 / 2.4, out=y)
    y *= 1.055
    y -= 0.055
    y[low] = linear
    return y


def to_rgb8(image: np.ndarray, linear: bool = True) -> np.ndarray:
    """A float image (H, W[, C]) in [0, 1] as uint8, sRGB-encoded when ``linear``."""
    a = np.asarray(image) if isinstance(image, (np.ndarray, list, tuple)) else np.zeros(0, object)
    if a.dtype.kind not in "biuf" or a.ndim not in (2, 3) or a.size == 0:
        raise ParameterError(f"image = {shown(image)}: expected an (H, W) or (H, W, C) array")
    if a.dtype == np.uint8:
        return a
    # NaN is black, +inf white, -inf black (a NaN cast to uint8 is undefined): fmax drops NaN,
    # so clipping with fmax and fmin is nan_to_num(nan=0, posinf=1, neginf=0) and a clip to
    # [0, 1] in two passes (but for the sign of a zero, which no 8-bit code keeps)
    y = a.astype(np.float32)
    np.fmax(y, 0.0, out=y)
    np.fmin(y, 1.0, out=y)
    if linear:
        alpha = y[..., 3].copy() if y.ndim == 3 and y.shape[-1] == 4 else None
        _srgb(y)
        if alpha is not None:  # alpha is not colour: store it as is
            y[..., 3] = alpha
    y *= 255.0
    y += 0.5
    return y.astype(np.uint8)


def write_png(path: str | os.PathLike[str], image: np.ndarray, linear: bool = True) -> Path:
    """Write (H, W), (H, W, 3) or (H, W, 4) ``image`` as PNG; float input is sRGB-encoded when
    ``linear`` (the default), else clipped. Returns the path."""
    a = np.asarray(image)
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[-1] not in (1, 3, 4)):
        raise ParameterError(f"{path}: cannot write an image of shape {a.shape} as PNG")
    if a.size == 0:
        raise ParameterError(f"{path}: cannot write an empty image (shape {a.shape}) as PNG")
    if a.dtype.kind not in "buif":
        raise ParameterError(f"{path}: cannot write an image of dtype {a.dtype} as PNG")
    if max(a.shape[:2]) > MAX_RES:
        raise ParameterError(f"{path}: image {a.shape[1]} x {a.shape[0]} is too large for PNG")
    if a.ndim == 3 and a.shape[-1] == 1:
        a = a[..., 0]
    rgb8 = to_rgb8(a, linear)
    target = as_path(path, "output file")
    with atomic_output(target) as tmp:
        save_png(rgb8, tmp)
    return target
