"""Depth lines of the thesis (section 5.1): depth normalisation, the signed depth-difference
contour filter (eq. 5.1) and the removal of isolated contour pixels (eq. 5.2).

Layout: every function takes a 2-D ``(H, W)`` image, as a numpy array (any real dtype) or a
Dr.Jit tensor, and returns a ``TensorXf`` of the same shape, already evaluated;
``np.asarray(result)`` gives numpy. The kernels run on the backend of their first Dr.Jit input,
else on the active variant's (LLVM, or CUDA for ``cuda_*``), see
:func:`mi_npr.kernels._stencil.backend`.

>>> import numpy as np
>>> from mi_npr.kernels import normalize_depth, depth_contours, remove_isolated
>>> Z = np.full((5, 6), np.inf, np.float32); Z[1:4, 1:4] = 2.0; Z[1, 5] = 2.0
>>> D = normalize_depth(Z, near=0.0, far=10.0)       # Z = 2 -> 0.2, background -> 1
>>> p = depth_contours(D, c=10.0, t=1.0)              # (1 - 0.2) * 10 - 1 >= 1: black
>>> (np.asarray(p) > 0).astype(int)                   # 1 px, on the near side of the step
array([[0, 0, 0, 0, 0, 0],
       [0, 1, 1, 1, 0, 1],
       [0, 1, 0, 1, 0, 0],
       [0, 1, 1, 1, 0, 0],
       [0, 0, 0, 0, 0, 0]])
>>> (np.asarray(remove_isolated(p)) > 0).astype(int)  # the lone pixel goes (eq. 5.2)
array([[0, 0, 0, 0, 0, 0],
       [0, 1, 1, 1, 0, 0],
       [0, 1, 0, 1, 0, 0],
       [0, 1, 1, 1, 0, 0],
       [0, 0, 0, 0, 0, 0]])

Ambiguities of the thesis and how they are resolved here:

- *Depth* ``D`` is normalised to [0, 1], 0 nearest, 1 farthest, linearly between the nearest and
  the farthest finite ``Z`` of the frame, or between user-given ``near`` and ``far``; background
  (``Z = +inf``) is 1. The thesis works on an OpenGL depth buffer whose far plane lies behind
  everything, so there the background is always farther than any object; with the frame's own
  range the farthest object pixel also gets 1, and its contour against the background vanishes.
  Give ``far`` (beyond the scene) where that matters. The :func:`~mi_npr.kernels.lines` chain
  (and ``npr_lines``) departs from this plain eq. 5.1 input in two ways, so that a
  lone sphere's whole silhouette is drawn at camera distances of 2 to 500 radii and scene scales
  of 1e-3 to 1e3, with ``far`` given or not: the background reads as ``D = 2`` (infinitely far:
  a full step from every finite pixel, whatever ``far`` is), and with ``far`` unset the span is at
  least 3x ``near`` (``far >= 4 near``), so a step is measured against at least the depth where it
  happens (scale-free) and a distant object's own relief is not stretched over [0, 1].
- *Neighbours* outside the image repeat the border pixel, except in eq. 5.2 where they count as
  no contour (0).
- *Eq. 5.1* is signed: a pixel lights up when a neighbour is *farther*, so contours are 1 px
  thick on the near side of a depth step, and gray levels are kept (no threshold).
- *Eq. 5.2* sums over the 3x3 block *including* the centre: ``ceil(sat(p_i - t0))`` is 1 exactly
  when ``p_i > t0``, so a pixel survives when at least 3 pixels of its block (itself and 2
  neighbours, for a pixel above ``t0``) are above ``t0``.

Non-finite values never spread: ``normalize_depth`` maps NaN and +-inf ``Z`` to 1 (background);
``depth_contours`` reads NaN depth as 1 (background) and clamps depth to [0, 1] (+inf -> 1,
-inf -> 0); ``remove_isolated`` reads NaN as 0 (no line) and clamps to [0, 1]. Every result is
finite and in [0, 1].
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import drjit as dr

from ..errors import ParameterError
from ._stencil import (
    Array,
    Field,
    Grid,
    Tensor,
    exact,
    finite,
    float_image,
    nonnegative,
    opaque,
    require,
    sanitize_depth,
    sanitize_lines,
    tensor,
    unit_interval,
    window,
)

#: Smallest normal float32: the span of a degenerate range (far == near) turns it into a step.
_F32_MIN = 1.1754943508222875e-38
#: Block size of the symbolic min/max reductions (one fused pass, then a tiny reduction).
_BLOCK = 4096


def check_range(near: float | None, far: float | None, who: str = "") -> None:
    """``near`` and ``far`` (each optional) must be finite, with ``near < far`` when both are
    given; ``who`` (a plugin or function name) prefixes the error."""
    require("near", near, finite)
    require("far", far, finite)
    if near is not None and far is not None and not float(near) < float(far):
        prefix = f"{who}: " if who else ""
        raise ParameterError(f"{prefix}near = {near!r}, far = {far!r}: near must be less than far")


def finite_range(z: Array) -> tuple[Array, Array]:
    """Smallest and largest finite value of ``z`` (+inf, -inf when none), as 1-lane arrays that
    stay on the device (no round trip to Python)."""
    finite = dr.isfinite(z)
    block = min(_BLOCK, dr.width(z))
    lo = dr.block_reduce(dr.ReduceOp.Min, dr.select(finite, z, dr.inf), block, mode="symbolic")
    hi = dr.block_reduce(dr.ReduceOp.Max, dr.select(finite, z, -dr.inf), block, mode="symbolic")
    dr.eval(lo, hi)  # one pass over z for both
    return dr.min(lo), dr.max(hi)


def depth_normalizer(
    z: Array,
    near: float | None = None,
    far: float | None = None,
    *,
    relative: bool = False,
    background: float = 1.0,
    frame: tuple[Array, Array] | None = None,
) -> Callable[[Array], Array]:
    """The per-pixel map ``Z -> D`` of :func:`normalize_depth` for the frame ``z`` (flat),
    to be fused into the kernel that reads the depth.

    ``relative`` (the :func:`~mi_npr.kernels.lines` chain): with ``far`` unset, the span
    ``far - near`` is at least ``near`` itself, i.e. ``far >= 2 near`` for ``near > 0``, so a
    depth step is measured against at least the depth where it happens and a distant object's
    own relief is not stretched over the whole [0, 1] range. ``background`` is the value of
    non-finite ``Z`` (the chain uses 2: the background lies infinitely far, beyond every finite
    pixel, whatever ``far`` is). ``frame``: the frame's smallest and largest finite ``Z``
    (:func:`finite_range`) where ``z`` is only a part of it (a strip), else ``z``'s own.
    """
    check_range(near, far)
    if near is None or far is None:
        lo, hi = finite_range(z) if frame is None else frame
        # One bound given: the other comes from the frame but never crosses it.
        n = lo if near is None else opaque(near, z)
        f = hi if far is None else opaque(far, z)
        if near is not None:
            f = dr.maximum(f, n)
        if far is not None:
            n = dr.minimum(n, f)
        elif relative:
            f = dr.maximum(f, n + 3.0 * dr.maximum(n, 0.0))
    else:
        n, f = opaque(near, z), opaque(far, z)
    # A division (not a reciprocal) so that far maps to exactly 1. far == near (a flat frame, or
    # one finite pixel): the smallest normal float makes it a step, 0 up to near and 1 beyond.
    # Halves (exact) keep far - near and Z - near finite even for depths near the float32 limit.
    h = dr.maximum(f * 0.5 - n * 0.5, _F32_MIN)
    span = dr.select(f > n, h, _F32_MIN)
    dr.eval(n, span)
    bg = float(background)

    def normalize(v: Array) -> Array:
        return dr.select(dr.isfinite(v), dr.clip((v * 0.5 - n * 0.5) / span, 0.0, 1.0), bg)

    return normalize


@exact
def normalize_depth(Z: Any, near: float | None = None, far: float | None = None) -> Tensor:
    """Depth ``Z`` (camera-space, +inf on background) normalised to ``D`` in [0, 1].

    ``D = clamp((Z - near) / (far - near), 0, 1)`` with 0 the nearest and 1 the farthest;
    ``near`` and ``far`` default to the smallest and largest finite ``Z`` of the frame (if only
    one is given, the other comes from the frame but never crosses it). Background and every
    non-finite ``Z`` (NaN, +-inf) are 1. When ``far == near`` (a frame at one depth) finite
    pixels at ``near`` are 0 and those beyond are 1. A frame without any finite ``Z`` is all 1.

    >>> import numpy as np
    >>> np.asarray(normalize_depth(np.array([[1.0, 3.0, np.inf]])))
    array([[0., 1., 1.]], dtype=float32)
    >>> np.asarray(normalize_depth(np.array([[1.0, 3.0, np.nan]]), near=0.0, far=4.0))
    array([[0.25, 0.75, 1.  ]], dtype=float32)
    """
    z, shape = float_image(Z, "Z")
    return tensor(depth_normalizer(z, near, far)(z), shape)


def contours(D: Field, c: float, t: float) -> Array:
    """Eq. 5.1 on a depth field (lazy): ``max_i sat((d_i - d0) c - t)``, 8 neighbours.

    ``x -> sat((x - d0) c - t)`` is non-decreasing for ``c >= 0`` (also in floating point), so
    the maximum of the eight terms is the term of the farthest neighbour: one subtraction after
    eight gathers. With ``t >= 0`` the centre's own term is ``sat(-t) = 0``, so including it in
    the maximum changes nothing.
    """
    farthest = None
    for dy, dx in window(3):
        if (dy, dx) != (0, 0):
            d = D.at(dy, dx)
            farthest = d if farthest is None else dr.maximum(farthest, d)
    return dr.clip((farthest - D.at()) * D.grid.opaque(c) - D.grid.opaque(t), 0.0, 1.0)


@exact
def depth_contours(D: Any, c: float, t: float) -> Tensor:
    """Eq. 5.1 of the thesis: ``p0 = max_i sat((d_i - d0) * c - t)`` over the 8 neighbours.

    ``D`` is normalised depth (0 near, 1 far; see :func:`normalize_depth`), ``c >= 0`` scales
    the depth difference and ``t >= 0`` is the threshold. Signed: a pixel lights up when its
    neighbours are *farther*, so a depth step gives a contour 1 px thick on its near side.
    Gray levels are kept: a step ``delta`` gives ``sat(delta * c - t)``, 0 below ``t / c`` and 1
    from ``(1 + t) / c`` on. Border pixels repeat outside the image. NaN depth reads as 1
    (background) and depth is clamped to [0, 1].

    >>> import numpy as np
    >>> D = np.array([[0.2, 0.2, 0.9]], np.float32)
    >>> np.asarray(depth_contours(D, c=2.0, t=0.4))          # (0.9 - 0.2) * 2 - 0.4 = 1.0
    array([[0., 1., 0.]], dtype=float32)
    """
    require("c", c, nonnegative)
    require("t", t, nonnegative)
    d, shape = float_image(D, "D")
    return tensor(contours(Field(d, Grid(shape, d), sanitize_depth), c, t), shape)


def isolated_removed(p: Field, t0: float) -> Array:
    """Eq. 5.2 on a line field (lazy). ``p0 * sat(n - 2)`` with ``n`` the integer count of the
    3x3 block's pixels above ``t0`` is ``p0`` when ``n >= 3`` and 0 otherwise; pixels outside
    the image are not counted (zero padding)."""
    grid, thr = p.grid, p.grid.opaque(t0)
    n = None
    for dy, dx in window(3):
        inside = None if (dy, dx) == (0, 0) else grid.inside(dy, dx)
        above = dr.select(p.at(dy, dx, inside) > thr, 1, 0)
        n = above if n is None else n + above
    return dr.select(n >= 3, p.at(), 0.0)


@exact
def remove_isolated(p: Any, t0: float = 0.5) -> Tensor:
    """Eq. 5.2 of the thesis: ``p0 <- p0 * sat(sum_i ceil(sat(p_i - t0)) - 2)``.

    The sum runs over the 3x3 block *including* the centre; ``ceil(sat(p_i - t0))`` is 1 when
    ``p_i > t0`` and 0 otherwise, and pixels outside the image count 0. So a pixel above ``t0``
    survives only with at least 2 neighbours above ``t0`` (a pixel at or below ``t0`` needs 3);
    surviving pixels keep their gray level. ``t0`` in [0, 1] separates contour pixels from the
    background (thesis: "usually chosen close to 0.5"). NaN reads as 0, values are clamped to
    [0, 1].

    >>> import numpy as np
    >>> p = np.zeros((3, 5), np.float32); p[1, 0] = 1.0; p[1, 2:5] = 0.8
    >>> np.asarray(remove_isolated(p))[1]                  # the lone pixel at x = 0 goes
    array([0. , 0. , 0. , 0.8, 0. ], dtype=float32)
    """
    require("t0", t0, unit_interval)
    v, shape = float_image(p, "p")
    return tensor(isolated_removed(Field(v, Grid(shape, v), sanitize_lines), t0), shape)
