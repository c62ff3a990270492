"""Stroke styles: the width, opacity, colour and dashes of every stroke, from its attributes.

A :class:`Style` is checked against :data:`STYLE_PARAMS` (one rule per field, a one-line
:class:`~mi_npr.errors.ParameterError` naming the field otherwise). Per vertex ``i`` of a
stroke of kind ``k`` and quantitative invisibility ``qi``:

- **width** ``w_i = width * kind_width[k] * hidden_width**min(qi, 1) * (1 - depth_falloff D_i)
  * taper_i`` px, with ``D_i`` the vertex's depth normalised over the frame's depth range
  (``Strokes.depth_range``: 0 nearest, 1 farthest, clipped) and ``taper_i`` rising
  smoothly (``3s^2 - 2s^3``) from ``taper_min`` at an open stroke's ends to 1 at ``taper`` px
  along it (no taper on closed strokes, nor where ``taper`` is 0);
- **opacity** 1, or with ``gray`` the gray level of eq. 5.1 of the thesis,
  ``sat((d_i - d_0) c - t)``, where ``d_0`` is the vertex's normalised depth and ``d_i`` that of
  the farthest surface one pixel beside it (``Stroke.depth_behind``; the background is 1): the
  thesis's depth-difference filter evaluated at the stroke instead of at a pixel, so a line
  fades where its depth step is small, and lines without a depth step (creases on one surface)
  vanish, as in the thesis, which draws depth discontinuities only;
- **colour** ``colors[k]`` (linear RGB), ``hidden_color`` for hidden strokes (``qi > 0``);
- **dashes** ``dash`` (on, off, on, ... px along the stroke) on hidden strokes, which are drawn
  only with ``hidden``.

Presets (:data:`STYLES`): ``technical`` (every stroke 1 px black, hidden lines dashed 4-3 px),
``illustration`` (depth-tapered widths from 2.4 px, tapered ends, lighter creases, no hidden
lines), ``thesis`` (1 px black, opacity from eq. 5.1 with the thesis's ``c = 40``, ``t = 1``,
no hidden lines).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..params import Param, coerce, real_range, rgb_color
from .model import KINDS, Stroke, sizes

#: The widest stroke, in pixels.
MAX_WIDTH = 256.0


def _kind_widths(v: Any) -> str | None:
    if not isinstance(v, Mapping):
        return "expected a mapping of edge kind to width factor"
    for k, x in v.items():
        if k not in KINDS:
            return f"unknown edge kind {k!r} (kinds: {', '.join(KINDS)})"
        if not _finite(x) or x < 0:
            return f"{k}: width factor {x!r} must be a finite number >= 0"
    return None


def _kind_colors(v: Any) -> str | None:
    if not isinstance(v, Mapping):
        return "expected a mapping of edge kind to linear RGB"
    for k, c in v.items():
        if k not in KINDS:
            return f"unknown edge kind {k!r} (kinds: {', '.join(KINDS)})"
        try:
            rgb = tuple(float(x) for x in c)
        except (TypeError, ValueError):
            return f"{k}: {c!r} is not an RGB colour"
        if len(rgb) != 3 or rgb_color(rgb):
            return f"{k}: {c!r} must be 3 finite values >= 0 (linear RGB)"
    return None


def _finite(x: Any) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool) and math.isfinite(x)


def parse_dash(v: Any) -> tuple[float, ...]:
    """A dash pattern from ``"4,3"`` or a sequence of numbers (``()``: solid); a
    :class:`ParameterError` for anything :func:`dash_pattern` refuses."""
    if isinstance(v, str):
        text = v.strip()
        if not text:
            return ()
        try:
            v = [float(x) for x in text.split(",")]
        except ValueError:
            raise ParameterError(f"dash = {text!r}: expected lengths in pixels, e.g. 4,3") from None
    problem = dash_pattern(v)
    if problem:
        raise ParameterError(f"dash = {v!r}: {problem}")
    return tuple(float(x) for x in v)


def dash_pattern(v: Any) -> str | None:
    """The rule of a dash pattern: on, off, ... lengths in pixels, finite, >= 0, not all 0
    (empty: solid)."""
    if isinstance(v, str):
        try:
            parse_dash(v)
        except ParameterError as e:
            return str(e).split(": ", 1)[-1]
        return None
    try:
        vals = [x for x in v]
    except TypeError:
        return "expected lengths in pixels, e.g. 4,3"
    if not vals:
        return None
    if not all(_finite(x) and x >= 0 for x in vals):
        return "lengths must be finite numbers >= 0 (pixels)"
    if sum(vals) <= 0:
        return "a dash pattern of zeros draws nothing"
    return None


#: The fields of :class:`Style`: each one's type, default (the ``technical`` preset's) and rule.
STYLE_PARAMS: tuple[Param, ...] = (
    Param("width", float, 1.0, "base width in pixels", real_range(0.0, MAX_WIDTH, open_lo=True)),
    Param("kind_width", dict, {}, "width factor per edge kind (1 where absent)", _kind_widths),
    Param("depth_falloff", float, 0.0, "width lost from nearest to farthest", real_range(0, 1)),
    Param("taper", float, 0.0, "length of the tapered ends, px (0: none)", real_range(0, 1e4)),
    Param("taper_min", float, 0.2, "width at the tip, relative", real_range(0, 1)),
    Param("hidden", bool, True, "draw hidden lines (qi > 0)"),
    Param("hidden_width", float, 1.0, "width factor of hidden lines", real_range(0, 1e3)),
    Param("dash", list, (4.0, 3.0), "dash pattern of hidden lines, px", dash_pattern),
    Param("colors", dict, {}, "linear RGB per edge kind (color where absent)", _kind_colors),
    Param("color", tuple, (0.0, 0.0, 0.0), "linear RGB of the strokes", rgb_color),
    Param("hidden_color", tuple, (0.0, 0.0, 0.0), "linear RGB of hidden lines", rgb_color),
    Param("gray", bool, False, "opacity from eq. 5.1's gray level"),
    Param("c", float, 40.0, "eq. 5.1 gain on the normalised depth difference", real_range(0)),
    Param("t", float, 1.0, "eq. 5.1 threshold", real_range(0)),
)


@dataclass(frozen=True)
class Style:
    """How strokes are drawn (module docstring); build with :func:`make_style` or
    :func:`style_of`, which check every field."""

    name: str = "custom"
    width: float = 1.0
    kind_width: Mapping[str, float] = field(default_factory=dict)
    depth_falloff: float = 0.0
    taper: float = 0.0
    taper_min: float = 0.2
    hidden: bool = True
    hidden_width: float = 1.0
    dash: tuple[float, ...] = (4.0, 3.0)
    colors: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)
    color: tuple[float, float, float] = (0.0, 0.0, 0.0)
    hidden_color: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gray: bool = False
    c: float = 40.0
    t: float = 1.0

    def to_dict(self) -> dict[str, Any]:
        """Every field, JSON-ready."""
        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = (
                {k: list(x) if isinstance(x, tuple) else x for k, x in v.items()}
                if isinstance(v, Mapping)
                else list(v)
                if isinstance(v, tuple)
                else v
            )
        return out

    def kind_color(self, stroke: Stroke) -> tuple[float, float, float]:
        """The linear RGB of ``stroke``."""
        if stroke.qi > 0:
            return tuple(self.hidden_color)  # type: ignore[return-value]
        return tuple(self.colors.get(stroke.kind, self.color))  # type: ignore[return-value]

    def drawn(self, stroke: Stroke) -> bool:
        """Whether ``stroke`` is drawn (hidden ones only with :attr:`hidden`)."""
        return stroke.qi == 0 or self.hidden

    def dashes(self, stroke: Stroke) -> tuple[float, ...]:
        """The dash pattern of ``stroke`` (``()``: solid)."""
        return tuple(self.dash) if stroke.qi > 0 else ()

    def widths(self, stroke: Stroke, depth_range: tuple[float, float]) -> np.ndarray:
        """Per-vertex widths in pixels (module docstring)."""
        return self.vertex_widths([stroke], depth_range)

    def opacity(self, stroke: Stroke, depth_range: tuple[float, float]) -> np.ndarray:
        """Per-vertex opacity in [0, 1] (module docstring)."""
        return self.vertex_opacity([stroke], depth_range)

    def vertex_widths(
        self,
        strokes: Sequence[Stroke],
        depth_range: tuple[float, float],
        size: np.ndarray | None = None,
    ) -> np.ndarray:
        """:meth:`widths` of every vertex of ``strokes``, one stroke after the other (``size``:
        their :func:`~mi_npr.strokes.model.sizes`, when known)."""
        if not strokes:
            return np.zeros(0)
        size = sizes(strokes) if size is None else size
        base = [
            self.width
            * float(self.kind_width.get(s.kind, 1.0))
            * (self.hidden_width if s.qi > 0 else 1.0)
            for s in strokes
        ]
        out = np.repeat(np.asarray(base, np.float64), size)
        if self.depth_falloff > 0:
            depth = np.concatenate([s.depth for s in strokes])
            out *= 1.0 - self.depth_falloff * _normalised(depth, depth_range)
        tapered = (size >= 2) & ~np.fromiter((s.closed for s in strokes), bool, len(strokes))
        if self.taper > 0 and tapered.any():
            pts = np.concatenate([s.points for s in strokes])
            arc, total = arc_lengths(pts, size)
            end = np.minimum(arc, np.repeat(total, size) - arc) / self.taper
            x = np.clip(end, 0.0, 1.0)
            factor = self.taper_min + (1.0 - self.taper_min) * (3 * x**2 - 2 * x**3)
            out *= np.where(np.repeat(tapered, size), factor, 1.0)
        return out

    def vertex_opacity(
        self,
        strokes: Sequence[Stroke],
        depth_range: tuple[float, float],
        size: np.ndarray | None = None,
    ) -> np.ndarray:
        """:meth:`opacity` of every vertex of ``strokes``, one stroke after the other (``size``
        as :meth:`vertex_widths`')."""
        n = int((sizes(strokes) if size is None else size).sum())
        if not self.gray or n == 0:
            return np.ones(n)
        d0 = _normalised(np.concatenate([s.depth for s in strokes]), depth_range)
        behind = np.concatenate(
            [s.depth_behind if s.depth_behind is not None else s.depth for s in strokes]
        )
        di = _normalised(behind, depth_range)
        return np.clip((di - d0) * self.c - self.t, 0.0, 1.0)


def arc_lengths(points: np.ndarray, size: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The arc length at each vertex (M,) of polylines given one after the other (``points``
    (M, 2), ``size`` (S,) vertices each, every size >= 1), and each one's length (S,)."""
    first = np.concatenate([[0], np.cumsum(size)[:-1]]).astype(np.int64)
    seg = np.hypot(*np.diff(points, axis=0).T) if len(points) > 1 else np.zeros(0)
    seg[first[1:] - 1] = 0.0  # no segment from one polyline to the next
    run = np.concatenate([[0.0], np.cumsum(seg)])
    owner = np.repeat(np.arange(len(size)), size)
    arc = run - run[first][owner]
    return arc, arc[first + np.asarray(size) - 1]


def _normalised(z: np.ndarray, depth_range: tuple[float, float]) -> np.ndarray:
    """``D = clip((z - near) / (far - near), 0, 1)``; the background (non-finite) is 1; a frame
    at one depth: 0 at ``near``, 1 beyond (as :func:`mi_npr.kernels.normalize_depth`)."""
    near, far = depth_range
    z = np.asarray(z, np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        d = (z - near) / (far - near) if far > near else np.where(z > near, 1.0, 0.0)
    return np.where(np.isfinite(z), np.clip(np.nan_to_num(d, nan=1.0), 0.0, 1.0), 1.0)


#: The presets (module docstring).
STYLES: dict[str, dict[str, Any]] = {
    "technical": {},
    "illustration": {
        "width": 2.4,
        "kind_width": {"silhouette": 1.0, "border": 0.9, "crease": 0.55, "material": 0.55},
        "depth_falloff": 0.6,
        "taper": 8.0,
        "taper_min": 0.15,
        "hidden": False,
        "color": (0.02, 0.015, 0.01),
    },
    "thesis": {"hidden": False, "gray": True, "c": 40.0, "t": 1.0},
}


def make_style(name: str = "custom", **values: Any) -> Style:
    """A :class:`Style` with ``values`` checked against :data:`STYLE_PARAMS` (the others at
    their defaults)."""
    known = {p.name: p for p in STYLE_PARAMS}
    checked: dict[str, Any] = {}
    for k, v in values.items():
        if k not in known:
            raise ParameterError(f"style: unknown parameter {k!r} (parameters: {', '.join(known)})")
        if k == "dash":
            checked[k] = parse_dash(v)
            continue
        checked[k] = coerce("style", known[k], v)
        if k == "colors":
            checked[k] = {kk: tuple(float(x) for x in c) for kk, c in checked[k].items()}
    return Style(name, **checked)


def style_of(name: str, **overrides: Any) -> Style:
    """The preset ``name`` of :data:`STYLES` with ``overrides`` (``None`` values are ignored);
    an unknown name or a bad value is a :class:`ParameterError`."""
    if name not in STYLES:
        raise ParameterError(f"style = {name!r}: expected one of {', '.join(STYLES)}")
    given = {k: v for k, v in overrides.items() if v is not None}
    return make_style(name, **{**STYLES[name], **given})
