"""Line width and ink density: the last two stages of the line chain.

Layout: a 2-D ``(H, W)`` line image in [0, 1] in (numpy or Dr.Jit), a ``TensorXf`` of the same
shape out (see :mod:`mi_npr.kernels.depth_lines`). Pixels outside the image count
as no ink (zero padding) for the width, and not at all for the density.

- :func:`widen_lines` -- every line ``width`` pixels wide. A 1-px line is dilated with a soft
  disc: pixel ``p`` gets ``max_q lines(q) * clip((width + 1) / 2 - |p - q|, 0, 1)``, so a line
  ``width`` px wide crosses ``width`` pixels' worth of ink (an axis-aligned 1-px line widened
  to 2 px gets half-ink neighbours on both sides, to 3 px full ones, to 4 px full ones plus
  half ones). Below 1 px the line keeps its pixels and is lightened: ``lines * width``.
- :func:`ink_density` -- the mean ink over a ``size`` x ``size`` window centred on each pixel
  (over the part of the window inside the image, so borders are not seen as sparse), the
  measure of "dense geometry" that the chain's ``max_density`` thins (thesis section 4.3:
  detail is left out where it would fill in).
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import drjit as dr

from ._stencil import (
    Array,
    Field,
    Grid,
    Tensor,
    exact,
    float_image,
    require,
    sanitize_lines,
    tensor,
)

#: Widest line (px): a width-w dilation reads (w + 1)^2 neighbours in one kernel.
MAX_WIDTH = 15.0
#: The window (px) over which the chain measures ink density.
DENSITY_WINDOW = 9


def line_width(v: Any) -> str | None:
    """The rule for ``line_width``: pixels in (0, MAX_WIDTH]."""
    ok = isinstance(v, numbers.Real) and not isinstance(v, bool) and 0 < v <= MAX_WIDTH
    return None if ok else f"must lie in (0, {MAX_WIDTH:g}] pixels"


def density_bound(v: Any) -> str | None:
    """The rule for ``max_density``: a share of ink in (0, 1] (1 = never thin)."""
    ok = isinstance(v, numbers.Real) and not isinstance(v, bool) and 0 < v <= 1
    return None if ok else "must lie in (0, 1] (share of inked pixels; 1 = off)"


def widened(p: Field, width: float) -> Array:
    """:func:`widen_lines` on an evaluated line field (lazy)."""
    if width <= 1.0:
        return p.at() * float(width)
    half = (width + 1.0) * 0.5
    r = math.ceil((width - 1.0) * 0.5)
    out = p.at()
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            w = min(max(half - math.hypot(dy, dx), 0.0), 1.0)
            if (dy, dx) == (0, 0) or w <= 0.0:
                continue
            v = p.at(dy, dx, p.grid.inside(dy, dx))
            out = dr.maximum(out, v * w if w < 1.0 else v)
    return out


@exact
def widen_lines(lines: Any, width: float) -> Tensor:
    """Every line of ``lines`` (gray levels in [0, 1], NaN = none) ``width`` pixels wide; see
    the module docstring.

    >>> import numpy as np
    >>> p = np.zeros((1, 7), np.float32); p[0, 3] = 1
    >>> np.asarray(widen_lines(p, 2.0)), float(np.asarray(widen_lines(p, 3.0)).sum())
    (array([[0. , 0. , 0.5, 1. , 0.5, 0. , 0. ]], dtype=float32), 3.0)
    """
    require("width", width, line_width)
    v, shape = float_image(lines, "lines")
    grid = Grid(shape, v)
    src = Field(v, grid, sanitize_lines)
    if width > 1.0:
        s = sanitize_lines(v)
        dr.eval(s)
        src = Field(s, grid)
    return tensor(widened(src, float(width)), shape)


def box_mean(p: Field, size: int) -> Array:
    """Mean of ``p`` over the part of the ``size`` x ``size`` window inside the image, in two
    separable passes; evaluates the row pass and returns the column pass lazily."""
    r = size // 2
    rows, count_x = None, None
    for dx in range(-r, r + 1):
        inside = None if dx == 0 else p.grid.inside(0, dx)
        v = p.at(0, dx, inside)
        c = 1.0 if inside is None else dr.select(inside, 1.0, 0.0)
        rows = v if rows is None else rows + v
        count_x = c if count_x is None else count_x + c
    dr.eval(rows)
    f = Field(rows, p.grid)
    total, count_y = None, None
    for dy in range(-r, r + 1):
        inside = None if dy == 0 else p.grid.inside(dy, 0)
        v = f.at(dy, 0, inside)
        c = 1.0 if inside is None else dr.select(inside, 1.0, 0.0)
        total = v if total is None else total + v
        count_y = c if count_y is None else count_y + c
    return total / (count_x * count_y)


@exact
def ink_density(lines: Any, size: int = DENSITY_WINDOW) -> Tensor:
    """The mean ink of ``lines`` over a ``size`` x ``size`` window (odd ``size`` >= 1) around
    each pixel, over the window's pixels inside the image.

    >>> import numpy as np
    >>> float(np.asarray(ink_density(np.ones((9, 9)), 3))[4, 4])
    1.0
    """
    if not (isinstance(size, numbers.Integral) and size >= 1 and size % 2 == 1):
        require("size", size, lambda _: "must be an odd integer >= 1")
    v, shape = float_image(lines, "lines")
    s = sanitize_lines(v)
    dr.eval(s)
    return tensor(box_mean(Field(s, Grid(shape, s)), int(size)), shape)
