"""Private machinery of the kernels: input checks, the flat pixel grid and neighbour reads.

Every kernel works on flat Dr.Jit arrays of ``H * W`` lanes, one lane per pixel in row-major
order (row 0 at the top). The backend is chosen once per call by :func:`backend`: that of the
first Dr.Jit input, else the active Mitsuba variant's (``cuda_*`` -> CUDA), else LLVM; other
inputs are brought to it, and everything a kernel creates (the pixel grid, opaque parameters)
is made on it, so a G-buffer rendered on a GPU stays there. A neighbour
``(dy, dx)`` is read with one ``dr.gather`` at a clamped index (pixels outside the image repeat
the border pixel), so a 3x3 stencil is one fused kernel with eight gathers; nothing is evaluated
until a kernel's result is needed as the source of another gather. Parameters that users vary
(``c``, ``t``, ``t0``, ...) enter the kernels as opaque values, so changing them does not
recompile anything; only the image size and the window size are baked into a kernel.
"""

from __future__ import annotations

import functools
import importlib
import math
import numbers
import sys
from collections.abc import Callable
from types import ModuleType
from typing import Any

import drjit as dr
import numpy as np

from ..errors import ParameterError

Shape = tuple[int, int]
#: A flat Dr.Jit array (``Float``, ``UInt32``, ``Bool``) of the kernel's backend.
Array = Any
#: An evaluated ``drjit.llvm.ad.TensorXf`` or ``drjit.cuda.ad.TensorXf``: a kernel's result.
Tensor = Any


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

_MODULES = {dr.JitBackend.LLVM: "drjit.llvm.ad", dr.JitBackend.CUDA: "drjit.cuda.ad"}


def backend(*inputs: Any) -> ModuleType:
    """The Dr.Jit AD module (``drjit.llvm.ad`` or ``drjit.cuda.ad``) a kernel call runs on.

    The backend of the first JIT input (a Dr.Jit array or tensor) wins; with numpy inputs only,
    the active Mitsuba variant's (``cuda_ad_rgb`` -> CUDA; Mitsuba is not imported for this);
    with neither, LLVM. The AD flavour is always used, so gradients flow through the kernels.
    """
    for x in inputs:
        if dr.is_jit_v(x):
            return importlib.import_module(_MODULES[dr.backend_v(x)])
    mi = sys.modules.get("mitsuba")
    variant = mi.variant() if mi is not None else None
    if variant is not None and variant.startswith("cuda_"):
        return importlib.import_module(_MODULES[dr.JitBackend.CUDA])
    return importlib.import_module(_MODULES[dr.JitBackend.LLVM])


def exact(fn: Callable[..., Any]) -> Callable[..., Any]:
    """A public kernel: traced and evaluated with Dr.Jit's ``FastMath`` flag off.

    With ``FastMath`` the CUDA backend compiles a float division to ``div.approx`` (off by an
    ulp or two, and 0 for a divisor beyond 2^126) and flushes denormals to zero; the kernels
    promise exact results (``far`` maps to exactly 1, float32 extremes stay finite, gray levels
    agree with the numpy references), so they use IEEE operations, and a CUDA result equals the
    LLVM one. The flag is part of Dr.Jit's kernel key: nothing else is affected.
    """

    @functools.wraps(fn)
    def run(*args: Any, **kwargs: Any) -> Any:
        with dr.scoped_set_flag(dr.JitFlag.FastMath, False):
            return fn(*args, **kwargs)

    return run


def _module(like: Any) -> ModuleType:
    """The AD module of ``like`` (an array of the kernel's backend, or the module itself)."""
    return like if isinstance(like, ModuleType) else backend(like)


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


def _jit_tensor(x: Any, B: ModuleType, vt: dr.VarType, ndim: int) -> tuple[int, ...] | None:
    """The shape of ``x`` when it is a non-empty Dr.Jit tensor of ``B``'s backend, element type
    ``vt`` and ``ndim`` dimensions (then it is used as it is), else ``None``."""
    if not (dr.is_tensor_v(x) and dr.is_jit_v(x)) or dr.backend_v(x) != dr.backend_v(B.Float):
        return None
    shape = tuple(int(s) for s in x.shape)
    if dr.type_v(x) != vt or len(shape) != ndim or min(shape, default=0) < 1:
        return None
    return shape


def float_image(x: Any, name: str, like: Any = None) -> tuple[Array, Shape]:
    """A 2-D float image (numpy or Dr.Jit) as a flat ``Float`` and its (H, W) shape, on the
    backend of ``like`` (an array or AD module; default :func:`backend` of ``x``)."""
    B = backend(x) if like is None else _module(like)
    shape = _jit_tensor(x, B, dr.VarType.Float32, 2)
    if shape is not None:  # a tensor of this backend passes without a copy
        return B.Float(x.array), (shape[0], shape[1])
    a = _to_numpy(x, name)
    _layout(a, name, None)
    # Dr.Jit maps a contiguous float32 array without copying: every kernel evaluates its result
    # before returning, so later changes to the caller's array cannot leak into it.
    a = np.ascontiguousarray(a, dtype=np.float32)
    return B.Float(a.reshape(-1)), (a.shape[0], a.shape[1])


def id_image(x: Any, name: str, like: Any = None) -> tuple[Array, Shape]:
    """A 2-D object-id image as a flat ``UInt32``: integers >= 0, or floats holding them
    exactly (the ids in ``mi.render``'s tensor); backend as :func:`float_image`."""
    B = backend(x) if like is None else _module(like)
    shape = _jit_tensor(x, B, dr.VarType.UInt32, 2)
    if shape is not None:
        return B.UInt32(x.array), (shape[0], shape[1])
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
    return B.UInt32(a.reshape(-1)), (a.shape[0], a.shape[1])


def vector_image(x: Any, name: str, like: Any = None) -> tuple[list[Array], Shape]:
    """A (H, W, 3) image (normals) as three flat ``Float`` planes; backend as
    :func:`float_image`."""
    B = backend(x) if like is None else _module(like)
    shape = _jit_tensor(x, B, dr.VarType.Float32, 3)
    if shape is not None and shape[2] == 3:  # de-interleaved on the device
        flat, i = B.Float(x.array), dr.arange(B.UInt32, shape[0] * shape[1]) * 3
        return [dr.gather(B.Float, flat, i + c) for c in range(3)], (shape[0], shape[1])
    a = _to_numpy(x, name)
    _layout(a, name, 3)
    a = np.ascontiguousarray(np.moveaxis(a, -1, 0), dtype=np.float32)
    planes = [B.Float(a[i].reshape(-1)) for i in range(3)]
    return planes, (a.shape[1], a.shape[2])


def same_shape(shapes: dict[str, Shape]) -> Shape:
    """The common shape of the named inputs, or an error naming both."""
    (first, s0), *rest = shapes.items()
    for name, s in rest:
        if s != s0:
            raise ParameterError(f"{name}: shape {s} differs from {first}'s {s0}")
    return s0


def tensor(v: Array, shape: Shape) -> Tensor:
    """Evaluate ``v`` (a flat ``Float``) and wrap it as an (H, W) tensor of its backend
    (``np.asarray`` gives a view on LLVM)."""
    dr.eval(v)
    return dr.tensor_t(type(v))(v, shape=shape)


def opaque(value: float, like: Any) -> Array:
    """A scalar ``Float`` on ``like``'s backend that enters kernels as a variable, so new values
    reuse the compiled kernel."""
    return dr.opaque(_module(like).Float, float(value))


class Grid:
    """Flat indices of an (H, W) image's pixels and of their neighbours at offsets (dy, dx).

    Neighbour indices are clamped to the image (the border pixel repeats); :meth:`inside` tells
    whether an offset really lies in the image, for kernels that pad with zeros instead.
    """

    def __init__(self, shape: Shape, like: Any) -> None:
        self.shape = (int(shape[0]), int(shape[1]))
        #: The AD module of the backend the grid lives on (``like``'s).
        self.B = _module(like)
        h, w = self.shape
        self.size = h * w
        i = dr.arange(self.B.Int32, self.size)
        self._y = i // w
        self._x = i - self._y * w
        self._rows: dict[int, Array] = {}
        self._cols: dict[int, Array] = {}

    def opaque(self, value: float) -> Array:
        """:func:`opaque` on the grid's backend."""
        return opaque(value, self.B)

    def zeros(self) -> Array:
        """A ``Float`` of zeros, one per pixel."""
        return dr.zeros(self.B.Float, self.size)

    def _row(self, dy: int) -> Array:
        if dy not in self._rows:
            self._rows[dy] = dr.clip(self._y + dy, 0, self.shape[0] - 1) * self.shape[1]
        return self._rows[dy]

    def _col(self, dx: int) -> Array:
        if dx not in self._cols:
            self._cols[dx] = dr.clip(self._x + dx, 0, self.shape[1] - 1)
        return self._cols[dx]

    def index(self, dy: int, dx: int) -> Array:
        """Flat index (``UInt32``) of the neighbour at (dy, dx), clamped to the image."""
        return self.B.UInt32(self._row(dy) + self._col(dx))

    def inside(self, dy: int, dx: int) -> Array:
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

    def at(self, dy: int = 0, dx: int = 0, active: Array | None = None) -> Any:
        if (dy, dx) == (0, 0):
            v = self.data  # the pixel itself: a plain load, no gather
        elif active is None:
            v = dr.gather(type(self.data), self.data, self.grid.index(dy, dx))
        else:  # inactive lanes read 0 before fn
            v = dr.gather(type(self.data), self.data, self.grid.index(dy, dx), active)
        return self.fn(v) if self.fn is not None else v


def sanitize_depth(d: Array) -> Array:
    """The depth policy of every kernel: NaN is background (1), values are clamped to [0, 1]
    (so +inf is 1 and -inf is 0)."""
    return dr.clip(dr.select(dr.isnan(d), 1.0, d), 0.0, 1.0)


def sanitize_lines(p: Array) -> Array:
    """The line-image policy: NaN is no line (0), values are clamped to [0, 1]."""
    return dr.clip(dr.select(dr.isnan(p), 0.0, p), 0.0, 1.0)
