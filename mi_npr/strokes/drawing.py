"""The ``strokes`` drawing's parameter table and its one step: extract, style, rasterise.

The drawing registry (:mod:`mi_npr.drawings`) registers :data:`STROKES_PARAMS` and calls
:func:`draw_strokes`; the plugin ``npr_strokes``, ``mi-npr render --strokes`` and
:func:`mi_npr.pipeline.render_layers` all go through it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import mitsuba as mi
import numpy as np

from ..kernels.ink import line_width
from ..params import Param, one_of
from ..scene import ObjectTable
from .extract import EXTRACT_PARAMS, extract_strokes
from .model import Strokes
from .raster import rasterize
from .style import STYLES, Style, dash_pattern, style_of

#: The longest segment of a stroke whose opacity varies along it (eq. 5.1), in pixels.
GRAY_SPACING = 2.0


def _dash(v: Any) -> str | None:
    return None if v == "" else dash_pattern(v)


#: The parameters of the ``strokes`` drawing (``npr_strokes``'s XML parameters, ``mi-npr
#: render --strokes``'s flags). ``None``: the style's value.
STROKES_PARAMS: tuple[Param, ...] = (
    Param("style", str, "technical", "stroke style: " + ", ".join(STYLES), one_of(tuple(STYLES))),
    Param("hidden", bool, None, "draw hidden lines, dashed (unset: the style's)"),
    Param(
        "line_width", float, None, "base stroke width in pixels (unset: the style's)", line_width
    ),
    Param(
        "dash", str, "", "dash pattern of hidden lines, px: on,off,... (unset: the style's)", _dash
    ),
    *EXTRACT_PARAMS,
)


@dataclass
class StrokeDrawing:
    """The strokes of one image, their style and their raster: ``alpha`` (H, W) float32
    coverage (the ``strokes.V`` layer) and ``ink`` (H, W, 3) premultiplied linear RGB."""

    strokes: Strokes
    style: Style
    alpha: np.ndarray
    ink: np.ndarray


def style_from(params: Mapping[str, Any]) -> Style:
    """The :class:`Style` of the drawing's parameters (the preset with ``hidden``,
    ``line_width`` and ``dash`` over it where set)."""
    dash = params.get("dash") or None
    return style_of(
        params.get("style") or "technical",
        hidden=params.get("hidden"),
        width=params.get("line_width"),
        dash=dash,
    )


def draw_strokes(
    scene: mi.Scene,
    sensor: mi.Sensor,
    table: ObjectTable,
    params: Mapping[str, Any],
    depth_range: tuple[float, float] | None = None,
    keep_topology: bool = True,
) -> StrokeDrawing:
    """Every stroke of ``scene`` seen by ``sensor``, styled and rasterised, with the drawing's
    ``params`` (all of :data:`STROKES_PARAMS`, checked). ``depth_range``: the frame's nearest
    and farthest finite depth (the G-buffer's ``Z``); ``keep_topology``: as
    :func:`~mi_npr.strokes.extract_strokes`'s."""
    style = style_from(params)
    kept = ("crease_angle", "chain_angle", "max_qi", "raytree_depth")
    strokes = extract_strokes(
        scene,
        sensor,
        table,
        crease_angle=params["crease_angle"],
        chain_angle=params["chain_angle"],
        max_qi=params["max_qi"],
        raytree_depth=params["raytree_depth"],
        depth_range=depth_range,
        params={k: params[k] for k in kept},
        resample=GRAY_SPACING if style.gray else None,
        keep_topology=keep_topology,
    )
    alpha, ink = rasterize(strokes, style)
    return StrokeDrawing(strokes, style, alpha, ink)


def depth_range_of(z: np.ndarray) -> tuple[float, float] | None:
    """The nearest and farthest finite depth of a ``Z`` layer (``None`` if it has none)."""
    finite = np.asarray(z)[np.isfinite(z)]
    return (float(finite.min()), float(finite.max())) if finite.size else None
