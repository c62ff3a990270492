"""Private machinery of the kernels: input checks, the flat pixel grid and neighbour reads.

Every kernel works on flat Dr.Jit arrays of ``H * W`` lanes, one lane per pixel in row-major
order (row 0 at the top), on the LLVM backend whatever Mitsuba variant is active. A neighbour
``(dy, dx)`` is read with one ``dr.gather`` at a clamped index (pixels outside the image repeat
the border pixel), so a 3x3 stencil is one fused kernel with eight gathers; nothing is evaluated
until a kernel's result is needed as the source of another gather. Parameters that users vary
(``c``, ``t``, ``t0``, ...) enter the kernels as opaque values, so changing them does not
recompile anything; only the image size and the window size are baked into a kernel.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from typing import Any

import drjit as dr
import numpy as np
from drjit.llvm.ad import Bool, Float, Int32, TensorXf, TensorXu, UInt32

from ..errors import ParameterError

Shape = tuple[int, int]


# ------------------------------------------------------------------ parameter rules
# Each rule returns what is wrong with a value (or None); the kernels and the plugin's parameter
# declarations (mi_npr.params.Param.check) share them.


#: The largest float32: parameters enter the float32 kernels, where a larger value is inf.
F32_MAX = 3.4028234663852886e38


def _real(v: Any) -> bool:
    return (
        isinstance(v, numbers.Real)
        and not isinstance(v, bool)
        and math.isfinite(v)
        and abs(v) <= F32_MAX
    )


def nonnegative(v: Any) -> str | None:
    return None if _real(v) and v >= 0 else "must be a finite number >= 0 (float32)"


def unit_interval(v: Any) -> str | None:
    return None if _real(v) and 0 <= v <= 1 else "must lie in [0, 1]"


def finite(v: Any) -> str | None:
    return None if v is None or _real(v) else "must be a finite number (float32)"


def require(name: str, value: Any, rule: Callable[[Any], str | None]) -> None:
    """Raise :class:`ParameterError` naming ``name`` if ``rule`` finds ``value`` wrong."""
    problem = rule(value)
    if problem:
        raise ParameterError(f"{name} = {value!r}: {problem}")


# ------------------------------------------------------------------ inputs and outputs


def _to_numpy(x: Any, name: str) -> np.ndarray:
    if dr.is_array_v(x):
        return np.asarray(x.numpy() if hasattr(x, "numpy") else x)
    try:
        return np.asarray(x)
    except (TypeError, ValueError) as e:
        raise ParameterError(f"{name}: not an array ({type(x).__name__}): {e}") from None


def _layout(a: np.ndarray, name: str, channels: int | None) -> None:
    want = "(H, W)" if channels is None else f"(H, W, {channels})"
    ndim = 2 if channels is None else 3
    if a.ndim != ndim or (channels is not None and a.shape[-1] != channels):
        raise ParameterError(f"{name}: expected a {want} array, got shape {a.shape}")
    if a.shape[0] < 1 or a.shape[1] < 1:
        raise ParameterError(f"{name}: the image is empty (shape {a.shape})")
    if a.dtype.kind not in "biuf":
        raise ParameterError(f"{name}: expected numbers, got dtype {a.dtype}")


def float_image(x: Any, name: str) -> tuple[Float, Shape]:
    """A 2-D float image (numpy or Dr.Jit) as a flat ``Float`` and its (H, W) shape."""
    if type(x) is TensorXf:  # our own tensors pass without a copy
        if x.ndim != 2:
            raise ParameterError(f"{name}: expected a (H, W) array, got shape {tuple(x.shape)}")
        h, w = (int(s) for s in x.shape)
        if h < 1 or w < 1:
            raise ParameterError(f"{name}: the image is empty (shape {(h, w)})")
        return x.array, (h, w)
    a = _to_numpy(x, name)
    _layout(a, name, None)
    # Dr.Jit maps a contiguous float32 array without copying: every kernel evaluates its result
    # before returning, so later changes to the caller's array cannot leak into it.
    a = np.ascontiguousarray(a, dtype=np.float32)
    return Float(a.reshape(-1)), (a.shape[0], a.shape[1])


def id_image(x: Any, name: str) -> tuple[UInt32, Shape]:
    """A 2-D object-id image as a flat ``UInt32``: integers >= 0, or floats holding them
    exactly (the ids in ``mi.render``'s tensor)."""
    if type(x) is TensorXu and x.ndim == 2 and min(x.shape) >= 1:
        return x.array, (int(x.shape[0]), int(x.shape[1]))
    a = _to_numpy(x, name)
    _layout(a, name, None)
    if a.dtype != np.uint32:  # the G-buffer's own type needs no check
        if a.dtype.kind == "f" and not (np.all(np.isfinite(a)) and np.all(a == np.round(a))):
            raise ParameterError(f"{name}: object ids must be integers (found NaN, inf, fractions)")
        if a.min() < 0:
            raise ParameterError(f"{name}: object ids must be >= 0 (found {a.min()})")
        if a.max() > np.iinfo(np.uint32).max:
            raise ParameterError(f"{name}: object ids must fit in 32 bits (found {a.max()})")
    a = np.ascontiguousarray(a, dtype=np.uint32)
    return UInt32(a.reshape(-1)), (a.shape[0], a.shape[1])


def vector_image(x: Any, name: str) -> tuple[list[Float], Shape]:
    """A (H, W, 3) image (normals) as three flat ``Float`` planes."""
    a = _to_numpy(x, name)
    _layout(a, name, 3)
    a = np.ascontiguousarray(np.moveaxis(a, -1, 0), dtype=np.float32)
    planes = [Float(a[i].reshape(-1)) for i in range(3)]
    return planes, (a.shape[1], a.shape[2])


def same_shape(shapes: dict[str, Shape]) -> Shape:
    """The common shape of the named inputs, or an error naming both."""
    (first, s0), *rest = shapes.items()
    for name, s in rest:
        if s != s0:
            raise ParameterError(f"{name}: shape {s} differs from {first}'s {s0}")
    return s0


def tensor(v: Float, shape: Shape) -> TensorXf:
    """Evaluate ``v`` and wrap it as an (H, W) tensor (``np.asarray`` gives a view)."""
    dr.eval(v)
    return TensorXf(v, shape=shape)


def opaque(value: float) -> Float:
    """A scalar that enters kernels as a variable, so new values reuse the compiled kernel."""
    return dr.opaque(Float, float(value))


class Grid:
    """Flat indices of an (H, W) image's pixels and of their neighbours at offsets (dy, dx).

    Neighbour indices are clamped to the image (the border pixel repeats); :meth:`inside` tells
    whether an offset really lies in the image, for kernels that pad with zeros instead.
    """

    def __init__(self, shape: Shape) -> None:
        self.shape = (int(shape[0]), int(shape[1]))
        h, w = self.shape
        self.size = h * w
        i = dr.arange(Int32, self.size)
        self._y = i // w
        self._x = i - self._y * w
        self._rows: dict[int, Int32] = {}
        self._cols: dict[int, Int32] = {}

    def _row(self, dy: int) -> Int32:
        if dy not in self._rows:
            self._rows[dy] = dr.clip(self._y + dy, 0, self.shape[0] - 1) * self.shape[1]
        return self._rows[dy]

    def _col(self, dx: int) -> Int32:
        if dx not in self._cols:
            self._cols[dx] = dr.clip(self._x + dx, 0, self.shape[1] - 1)
        return self._cols[dx]

    def index(self, dy: int, dx: int) -> UInt32:
        """Flat index of the neighbour at (dy, dx), clamped to the image."""
        return UInt32(self._row(dy) + self._col(dx))

    def inside(self, dy: int, dx: int) -> Bool:
        """True where the neighbour at (dy, dx) lies inside the image."""
        y, x = self._y + dy, self._x + dx
        return (y >= 0) & (y < self.shape[0]) & (x >= 0) & (x < self.shape[1])


def window(n: int) -> list[tuple[int, int]]:
    """The offsets of an n x n window (n odd), row by row, centre included."""
    r = n // 2
    return [(dy, dx) for dy in range(-r, r + 1) for dx in range(-r, r + 1)]


#: The 4-neighbourhood (up, left, right, down).
CROSS = ((-1, 0), (0, -1), (0, 1), (1, 0))


class Field:
    """An image read at neighbour offsets: ``at(dy, dx)`` gathers ``data`` at the clamped index
    and applies ``fn`` to the values read (so a per-pixel map, such as the depth normalisation,
    is fused into the kernel that reads it instead of being a kernel of its own)."""

    def __init__(self, data: Any, grid: Grid, fn: Callable[[Any], Any] | None = None) -> None:
        self.data, self.grid, self.fn = data, grid, fn

    def at(self, dy: int = 0, dx: int = 0, active: Bool | None = None) -> Any:
        if (dy, dx) == (0, 0):
            v = self.data  # the pixel itself: a plain load, no gather
        elif active is None:
            v = dr.gather(type(self.data), self.data, self.grid.index(dy, dx))
        else:  # inactive lanes read 0 before fn
            v = dr.gather(type(self.data), self.data, self.grid.index(dy, dx), active)
        return self.fn(v) if self.fn is not None else v


def sanitize_depth(d: Float) -> Float:
    """The depth policy of every kernel: NaN is background (1), values are clamped to [0, 1]
    (so +inf is 1 and -inf is 0)."""
    return dr.clip(dr.select(dr.isnan(d), 1.0, d), 0.0, 1.0)


def sanitize_lines(p: Float) -> Float:
    """The line-image policy: NaN is no line (0), values are clamped to [0, 1]."""
    return dr.clip(dr.select(dr.isnan(p), 0.0, p), 0.0, 1.0)
