"""Selective dilation of the depth buffer (eqs. 5.3-5.4 of the thesis): a pre-filter that fills
small holes (1-pixel "holes" that eq. 5.2 cannot remove) without growing objects.

Layout: a 2-D ``(H, W)`` image in, a ``TensorXf`` of the same shape and backend out (see
:mod:`mi_npr.kernels.depth_lines`).

Ambiguities resolved: the thesis works on reversed depth ``R = 1 - D`` (0 = far
background) and defines

- eq. 5.3, the dilation ``DD = max_S R`` over the n x n window ``S`` (odd ``n``, centre included);
- eq. 5.4, ``SD = DD`` where ``Na > N_neighbours / 2``, else ``R``; ``Na`` counts the
  ``n * n - 1`` neighbours (centre excluded) with ``R`` strictly above the window mean ``m``
  (centre included in the mean);

pixels outside the image repeat the border pixel; ``iterations`` applies the filter that many
times (0 returns the input); the result is given back as depth (``1 - SD``). ``R_i > m`` is
decided exactly, as ``n * n * d_i < sum_S d`` in float64 (a float32 mean would break exact
ties by rounding). Depth is read with the same policy as eq. 5.1:
NaN is background (1) and values are clamped to [0, 1], so the result is finite.
"""

from __future__ import annotations

import numbers
from typing import Any

import drjit as dr

from ..params import MAX_ITERATIONS
from ._stencil import (
    Array,
    Field,
    Grid,
    Tensor,
    exact,
    float_image,
    require,
    sanitize_depth,
    tensor,
    window,
)

#: Largest window: an n x n window is n * n gathers unrolled into one kernel.
MAX_SIZE = 15


def _integer(v: Any) -> bool:
    return isinstance(v, numbers.Integral) and not isinstance(v, bool)


def window_size(v: Any) -> str | None:
    """The rule for ``size``: an odd integer in [3, MAX_SIZE]."""
    if not _integer(v) or v < 3 or v % 2 == 0:
        return "must be an odd integer >= 3"
    return None if v <= MAX_SIZE else f"must be at most {MAX_SIZE}"


def iteration_count(v: Any) -> str | None:
    """The rule for ``iterations``: an integer in 0..MAX_ITERATIONS."""
    if not _integer(v) or v < 0:
        return "must be an integer >= 0"
    return None if v <= MAX_ITERATIONS else f"must be at most {MAX_ITERATIONS}"


def dilated(D: Field, size: int) -> Array:
    """One selective dilation (eqs. 5.3-5.4) of a depth field (lazy).

    The test ``R_i > m`` on reversed depth ``R = 1 - D`` is ``d_i < mean(d)``, decided as
    ``N * d_i < sum(d)`` in float64 (``N = n * n``): the float32 depths, their sum and the
    products are exact there (for depths in [2^-29, 2], and 0), so ties are ties, not float32
    rounding of a mean. The value taken is the window's smallest depth (``1 - max_S R``), so
    pixels that keep their value keep it bit for bit.
    """
    offsets = window(size)
    depths = [D.at(dy, dx) for dy, dx in offsets]
    wide = [dr.float64_array_t(type(d))(d) for d in depths]
    centre = offsets.index((0, 0))
    total, nearest = wide[0], depths[0]
    for w, d in zip(wide[1:], depths[1:], strict=True):
        total, nearest = total + w, dr.minimum(nearest, d)
    count = float(len(depths))
    n_above = None
    for k, w in enumerate(wide):
        if k != centre:
            above = dr.select(w * count < total, 1, 0)
            n_above = above if n_above is None else n_above + above
    # Na > (n*n - 1) / 2 with an even n*n - 1: Na >= (n*n - 1) / 2 + 1.
    return dr.select(n_above > (len(depths) - 1) // 2, nearest, depths[centre])


@exact
def selective_dilation(D: Any, size: int = 3, iterations: int = 1) -> Tensor:
    """Selective dilation of normalised depth ``D`` (eqs. 5.3-5.4 of the thesis).

    On reversed depth ``R = 1 - D`` with an n x n window (``size`` odd, >= 3): where more than
    half of the ``n * n - 1`` neighbours lie above the window mean (nearer than average, so the
    pixel is a far "hole" among near pixels) the pixel takes the window's maximum of ``R``
    (eq. 5.3, a gray-level dilation); elsewhere it keeps its value (eq. 5.4). Smooth object
    boundaries stay where they are; a 3x3 window fills 1-pixel holes. ``iterations`` repeats it.
    Returns depth (0 near, 1 far). NaN reads as 1, values are clamped to [0, 1].

    >>> import numpy as np
    >>> D = np.full((5, 5), 0.25, np.float32); D[2, 2] = 1.0    # a 1-pixel hole in a surface
    >>> float(np.asarray(selective_dilation(D))[2, 2])
    0.25
    """
    require("size", size, window_size)
    require("iterations", iterations, iteration_count)
    d, shape = float_image(D, "D")
    grid = Grid(shape, d)
    field = Field(d, grid, sanitize_depth)
    out = field.at()
    for _ in range(iterations):
        out = dilated(field, size)
        dr.eval(out)
        field = Field(out, grid)
    return tensor(out, shape)
