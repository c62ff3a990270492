"""The line losses of :mod:`mi_npr.ad` and the reading of target drawings."""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np
from PIL import Image, ImageDraw, UnidentifiedImageError

from ..errors import InputError, ParameterError, as_path, check_input_file, shown

#: Standard deviations (pixels) of :func:`blurred_l2`'s Gaussians by default.
SCALES = (1.0, 2.0, 4.0, 8.0, 16.0)


def _float32(value: Any, name: str, expected: str) -> np.ndarray:
    """``value`` as a float32 array, or a :class:`ParameterError` naming ``name``."""
    try:
        return np.asarray(value, np.float32)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} = {shown(value)}: expected {expected}") from None


def _flat(image: Any, name: str) -> tuple[Any, tuple[int, int]]:
    """An (H, W) image as a flat ``mi.Float`` (a Dr.Jit tensor keeps its AD graph)."""
    if image is None:
        raise ParameterError(f"{name} = None: expected an (H, W) image (array or Dr.Jit tensor)")
    if dr.is_tensor_v(image) and dr.is_jit_v(image):
        shape = tuple(int(v) for v in image.shape)
        flat = mi.Float(image.array)
    else:
        a = _float32(image, name, "an (H, W) image (array or Dr.Jit tensor)")
        shape = a.shape
        flat = mi.Float(np.ascontiguousarray(a).reshape(-1))
    if len(shape) != 2 or min(shape) < 1:
        raise ParameterError(f"{name}: expected an (H, W) image, got shape {shape}")
    return flat, (shape[0], shape[1])


def _check_sigma(sigma: Any) -> float:
    if isinstance(sigma, bool) or not isinstance(sigma, (int, float)) or not sigma >= 0:
        raise ParameterError(f"sigma = {sigma!r}: must be a number >= 0")
    if not math.isfinite(sigma):
        raise ParameterError(f"sigma = {sigma!r}: must be finite")
    return float(sigma)


def blur(image: Any, sigma: float) -> mi.TensorXf:
    """``image`` ((H, W)) convolved with a Gaussian of standard deviation ``sigma`` pixels,
    truncated at ``3 sigma`` and normalised, separably, the border pixels repeated; in Dr.Jit,
    so gradients flow through it. ``sigma = 0`` returns the image.

    >>> img = np.zeros((9, 9), np.float32); img[4, 4] = 1.0
    >>> b = np.asarray(blur(img, 1.0))
    >>> round(float(b.sum()), 5), bool(b[4, 4] == b.max()), round(float(b[4, 3] / b[4, 4]), 4)
    (1.0, True, 0.6065)
    """
    sigma = _check_sigma(sigma)
    x, (h, w) = _flat(image, "blur")
    if sigma == 0:
        return mi.TensorXf(x, shape=(h, w))
    return mi.TensorXf(dr.custom(_Blur, x, h, w, sigma), shape=(h, w))


def _blur_pass(x: Any, h: int, w: int, sigma: float, along_x: bool, adjoint: bool) -> mi.Float:
    """One axis of :func:`blur` on the flat (h, w) image ``x``: ``y[p] = sum_k w_k x[clip(p +
    k)]``, or with ``adjoint`` its transpose ``x[q] = sum_d W(q, d) y[q + d]`` (``0 <= q + d <
    L``), ``W(q, d) = w_-d`` inside, and at an end the weights of every tap clipped onto it:
    ``sum_(k <= -d) w_k`` at ``q = 0``, ``sum_(k >= -d) w_k`` at ``q = L - 1``."""
    length = w if along_x else h
    if length == 1:  # every tap clipped onto the one pixel: the identity
        return mi.Float(x)
    r = max(1, math.ceil(3.0 * sigma))
    taps = np.arange(-r, r + 1)
    weights = np.exp(-0.5 * (taps / sigma) ** 2)
    weights /= weights.sum()
    idx = dr.arange(mi.UInt32, h * w)
    px, py = mi.Int32(idx % w), mi.Int32(idx // w)
    pos = px if along_x else py
    acc = mi.Float(0.0)
    for k, wt in zip(taps, weights, strict=True):
        k = int(k)
        at = dr.clip(pos + k, 0, length - 1)
        q = py * w + at if along_x else at * w + px
        if not adjoint:
            acc += float(wt) * dr.gather(mi.Float, x, mi.UInt32(q))
            continue
        d = k  # the output at q + d read this pixel through tap -d
        ok = (pos + d >= 0) & (pos + d < length)
        first, last = float(weights[: r - d + 1].sum()), float(weights[r - d :].sum())
        wq = dr.select(pos == 0, first, dr.select(pos == length - 1, last, float(weights[r - d])))
        acc += dr.select(ok, wq * dr.gather(mi.Float, x, mi.UInt32(q), ok), 0.0)
    return acc


class _Blur(dr.CustomOp):
    """:func:`blur` with a backward pass of gathers (its transpose, :func:`_blur_pass`): Dr.Jit
    would transpose each of the taps' gathers into an atomic scatter-add."""

    def eval(self, x: Any, h: int, w: int, sigma: float) -> mi.Float:
        self.shape = (h, w, sigma)
        return self._apply(x, False)

    def _apply(self, x: Any, adjoint: bool) -> mi.Float:
        for along_x in (False, True) if adjoint else (True, False):
            x = _blur_pass(x, *self.shape, along_x, adjoint)
            dr.eval(x)
        return x

    def forward(self) -> None:
        self.set_grad_out(self._apply(self.grad_in("x"), False))

    def backward(self) -> None:
        self.set_grad_in("x", self._apply(self.grad_out(), True))

    def name(self) -> str:
        return "blur"


def _target(target: Any, shape: tuple[int, int]) -> np.ndarray:
    t = _float32(target, "target", "an (H, W) drawing (read_drawing reads a file)")
    if t.shape != shape:
        raise ParameterError(
            f"the drawing is {t.shape[-1] if t.ndim else '?'}x{t.shape[0] if t.ndim else '?'}, "
            f"the render {shape[1]}x{shape[0]}: they must be the same size"
        )
    if not np.all(np.isfinite(t)):
        raise ParameterError("the drawing has non-finite values")
    return t


def blurred_l2(rendered: Any, target: Any, scales: Sequence[float] = SCALES) -> mi.Float:
    """The multi-scale blurred L2 between a rendered line image and a target drawing (module
    docstring); a scalar ``mi.Float`` whose gradient reaches ``rendered``."""
    r, shape = _flat(rendered, "rendered")
    t = _target(target, shape)
    if not scales:
        raise ParameterError("scales: give at least one")
    total = mi.Float(0.0)
    rt = mi.TensorXf(r, shape=shape)
    for s in scales:
        d = blur(rt, s).array - blur(t, s).array
        total += dr.mean(d * d)
    return total / len(scales)


def chamfer(rendered: Any, target: Any) -> mi.Float:
    """The mean distance (pixels) of the rendered ink to the target's lines (module docstring);
    a scalar ``mi.Float`` whose gradient reaches ``rendered``. A target without any line is a
    :class:`ParameterError`."""
    r, shape = _flat(rendered, "rendered")
    t = _target(target, shape)
    lines = t > 0.5
    if not lines.any():
        raise ParameterError("chamfer: the drawing has no line (no pixel of ink above 0.5)")
    from scipy.ndimage import distance_transform_edt  # lazy: scipy's import is slow

    dist = distance_transform_edt(~lines).astype(np.float32)
    d = mi.Float(np.ascontiguousarray(dist).reshape(-1))
    return dr.sum(r * d) / dr.maximum(dr.sum(r), 1e-8)


_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _svg_ink(path: str) -> np.ndarray:
    """The ink of an SVG of straight paths (``M``/``L``/``Z``, polylines and lines, as
    mi-npr writes them), drawn at its ``width x height`` with each element's stroke width."""
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as e:
        raise InputError(f"{path}: not a valid SVG ({e})") from None
    try:
        w = round(float(_NUMBER.match(root.get("width", "")).group()))  # type: ignore[union-attr]
        h = round(float(_NUMBER.match(root.get("height", "")).group()))  # type: ignore[union-attr]
    except (AttributeError, ValueError):
        raise InputError(f"{path}: the SVG has no width and height in pixels") from None
    img = Image.new("L", (w, h), 0)
    draw = ImageDraw.Draw(img)
    for el in root.iter():
        tag = el.tag.rsplit("}", 1)[-1]
        width = max(1, round(float(el.get("stroke-width", "1") or 1)))
        chains: list[list[tuple[float, float]]] = []
        if tag == "path":
            for part in re.split(r"(?=[Mm])", el.get("d", "")):
                nums = [float(v) for v in _NUMBER.findall(part)]
                pts = list(zip(nums[0::2], nums[1::2], strict=False))
                if "Z" in part.upper() and pts:
                    pts.append(pts[0])
                chains.append(pts)
        elif tag == "polyline":
            nums = [float(v) for v in _NUMBER.findall(el.get("points", ""))]
            chains.append(list(zip(nums[0::2], nums[1::2], strict=False)))
        elif tag == "line":
            chains.append(
                [
                    (float(el.get(k, 0)), float(el.get(k2, 0)))
                    for k, k2 in (("x1", "y1"), ("x2", "y2"))
                ]
            )
        for pts in chains:
            if len(pts) > 1:
                draw.line(pts, fill=255, width=width)
    return np.asarray(img, np.float32) / 255.0


def read_drawing(path: str | os.PathLike[str]) -> np.ndarray:
    """A target drawing as ink in [0, 1], (H, W) float32: a PNG (or any image Pillow reads) of
    dark ink on light paper, ``1 - luminance`` (a transparent pixel is paper), or an SVG of
    straight paths. A missing or unreadable file is an :class:`~mi_npr.errors.InputError`
    naming it."""
    name = os.fspath(as_path(path, "read_drawing: path"))
    check_input_file(name, InputError)
    if name.lower().endswith(".svg"):
        return _svg_ink(name)
    try:
        with Image.open(name) as im:
            rgba = np.asarray(im.convert("RGBA"), np.float32) / 255.0
    except (UnidentifiedImageError, OSError) as e:
        raise InputError(f"{name}: not an image Pillow reads ({e})") from None
    lum = rgba[..., :3] @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    return (1.0 - lum) * rgba[..., 3]
