"""The files of the ``strokes`` drawing: ``<stem>_strokes.svg``, ``<stem>_strokes.json`` and
``<stem>_strokes.png``.

**SVG** (``width`` x ``height`` user units = pixels, y down)::

    <svg viewBox="0 0 W H" xmlns:inkscape="...">
      <g id="strokes" inkscape:groupmode="layer" inkscape:label="strokes" fill="none"
         stroke-linecap="round" stroke-linejoin="round">
        <g id="silhouette" inkscape:groupmode="layer" inkscape:label="silhouette">
          <g id="silhouette.sphere" inkscape:label="sphere" data-object-id="2"
             data-name="sphere">
            <path class="visible" data-stroke="0" data-qi="0" stroke="#000000"
                  stroke-width="1" d="M 10.521 3.5 L ... Z"/>
            <path class="hidden" data-stroke="5" data-qi="1" stroke-dasharray="4 3" .../>
            <path class="visible" data-stroke="7" fill="#000000" stroke="none" d="..."/>
          </g>
        </g>
        <g id="crease" ...> ... </g>
      </g>
    </svg>

One Inkscape layer per edge kind (in :data:`~mi_npr.strokes.KINDS` order), one group per
object inside it (the object of the stroke's first vertex), one ``<path>`` per drawn stroke
(``data-stroke``: its index in the JSON file; a stroke transparent everywhere is left out).
A stroke of constant width is a stroked path (``stroke-width``); one whose width varies
(depth, tapers) is its *filled outline*: the centreline offset by half the width on either
side at every vertex (along the vertex normal of :func:`mi_npr.strokes.outlines.normals_2d`),
closed (a closed stroke: its two offset rings, ``fill-rule="evenodd"``). Dashed strokes
(hidden lines) stay stroked paths with ``stroke-dasharray`` at their mean width. A stroke of
one opacity below 1 carries it (``stroke-opacity``, ``fill-opacity``); a stroke whose opacity
varies along it (the ``thesis`` style) is a ``<g>`` of stroked paths, one per run of segments
of one opacity (in steps of 1/32; the JSON has it per vertex). Coordinates have 3 decimals
(0.0005 px). No raster image is embedded.

**JSON** (UTF-8; non-finite numbers are ``null``)::

    {"format": "mi-npr-strokes", "version": 1,
     "width": W, "height": H,
     "camera": {"to_world": 4x4, "resolution": [W, H], "fov": deg, ...},
     "depth_range": [nearest, farthest],       # the frame's finite depths (eq. 5.1's range)
     "params": {"crease_angle": ..., "chain_angle": ..., "max_qi": ...},
     "style": {"name": "technical", "width": 1.0, ...},
     "kinds": ["silhouette", "border", ...],
     "objects": {"1": "name", ...},
     "strokes": [
       {"id": 0, "kind": "silhouette", "object_id": 2, "object": "sphere",
        "qi": 0, "visible": true, "through_glass": false, "closed": true, "drawn": true,
        "points": [[x, y], ...],                # film positions, pixels (y down)
        "position": [[x, y, z], ...],           # world positions
        "depth": [...],                         # camera depth along the view axis
        "depth_behind": [...],                  # farthest depth 1 px beside (null: background)
        "object_ids": [...], "prims": [...],    # object and primitive at each vertex
        "width": [...], "opacity": [...]}]}     # the style's, per vertex

Every stroke is listed, drawn or not (``drawn``: hidden lines with ``hidden`` off are not).

**PNG**: the drawn strokes in their colours on white paper (sRGB), anti-aliased as the
``strokes.V`` layer (:mod:`mi_npr.strokes.raster`).
"""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from ..compose import PAPER
from ..strokes.drawing import StrokeDrawing
from ..strokes.model import KINDS, Stroke
from ..strokes.outlines import normals_2d
from ..strokes.raster import on_background
from ._atomic import check_writable_dir, output_set
from .png import linear_to_srgb, write_png
from .svg import xml_id
from .text import quoteattr, write_text

_INKSCAPE = "http://www.inkscape.org/namespaces/inkscape"
#: Opacity levels of the SVG paths of a stroke whose opacity varies.
OPACITY_STEPS = 32


def _num(v: float) -> str:
    t = f"{v:.3f}".rstrip("0").rstrip(".")
    return "0" if t in ("-0", "") else t


def _ring(points: np.ndarray, closed: bool) -> str:
    coords = [f"{_num(x)} {_num(y)}" for x, y in np.asarray(points, np.float64).tolist()]
    if not coords:
        return ""
    d = "M " + coords[0]
    if len(coords) > 1:
        d += " L " + " ".join(coords[1:])
    return d + (" Z" if closed else "")


def _hex(rgb: Any) -> str:
    s = (linear_to_srgb(np.asarray(rgb, np.float32)) * 255.0 + 0.5).astype(np.uint8)
    return "#" + "".join(f"{int(v):02x}" for v in s)


def outline_path(stroke: Stroke, widths: np.ndarray) -> str:
    """The ``d`` of a variable-width stroke's filled outline (module docstring)."""
    n = normals_2d(stroke.points, stroke.closed)
    half = (np.asarray(widths, np.float64) / 2.0)[:, None]
    left, right = stroke.points + n * half, stroke.points - n * half
    if stroke.closed:
        return _ring(left, True) + " " + _ring(right[::-1], True)
    return _ring(np.concatenate([left, right[::-1]]), True)


def stroke_svg(drawing: StrokeDrawing, title: str | None = None) -> str:
    """The SVG text of a :class:`~mi_npr.strokes.drawing.StrokeDrawing` (module docstring)."""
    st, style = drawing.strokes, drawing.style
    w, h = st.width, st.height
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" xmlns:inkscape="{_INKSCAPE}" '
        f'version="1.1" width="{w}" height="{h}" viewBox="0 0 {w} {h}">',
    ]
    if title:
        out.append(f"<title>{_text(title)}</title>")
    out.append(
        '<g id="strokes" inkscape:groupmode="layer" inkscape:label="strokes" fill="none" '
        'stroke-linecap="round" stroke-linejoin="round">'
    )
    taken = {"strokes", *KINDS}
    for kind in KINDS:
        groups: dict[int, list[str]] = {}
        for i, s in enumerate(st.strokes):
            if s.kind != kind or not style.drawn(s):
                continue
            if not np.any(style.opacity(s, st.depth_range) > 0):
                continue  # transparent everywhere (eq. 5.1 finds no depth step along it)
            groups.setdefault(int(s.object_id[0]), []).append(_path(i, s, drawing))
        if not groups:
            continue
        out.append(
            f'  <g id="{kind}" inkscape:groupmode="layer" inkscape:label="{kind}" '
            f'data-kind="{kind}">'
        )
        for oid in sorted(groups):
            name = st.name_of(oid)
            gid = xml_id(f"{kind}.{name}", taken, str(oid))
            label = quoteattr(_text(name))
            out.append(
                f"    <g id={quoteattr(gid)} inkscape:label={label} "
                f'data-object-id="{oid}" data-name={label}>'
            )
            out.extend(groups[oid])
            out.append("    </g>")
        out.append("  </g>")
    out.append("</g>")
    out.append("</svg>")
    return "\n".join(out) + "\n"


def _path(i: int, s: Stroke, drawing: StrokeDrawing) -> str:
    style, rng = drawing.style, drawing.strokes.depth_range
    widths = style.widths(s, rng)
    opacity = style.opacity(s, rng)
    color = _hex(style.kind_color(s))
    dash = style.dashes(s)
    cls = "visible" if s.qi == 0 else "hidden"
    attrs = f'class="{cls}" data-stroke="{i}" data-qi="{s.qi}"'
    if s.through_glass:
        attrs += ' data-through-glass="true"'
    if float(np.ptp(opacity)) > 1e-9:
        return _runs(attrs, s, widths, opacity, color, dash)
    if opacity[0] < 1.0:
        attrs += f' stroke-opacity="{opacity[0]:.4g}" fill-opacity="{opacity[0]:.4g}"'
    constant = float(np.ptp(widths)) <= 1e-9 * max(1.0, float(widths.max()))
    if dash or constant:
        return f"      <path {attrs} {_stroked(s.points, s.closed, widths, color, dash)}/>"
    rule = ' fill-rule="evenodd"' if s.closed else ""
    return f'      <path {attrs} fill="{color}" stroke="none"{rule} d="{outline_path(s, widths)}"/>'


def _stroked(
    points: np.ndarray, closed: bool, widths: np.ndarray, color: str, dash: tuple[float, ...]
) -> str:
    extra = f' stroke-dasharray="{" ".join(_num(x) for x in dash)}"' if dash else ""
    width = _num(float(np.mean(widths)))
    return f'stroke="{color}" stroke-width="{width}"{extra} d="{_ring(points, closed)}"'


def _runs(
    attrs: str,
    s: Stroke,
    widths: np.ndarray,
    opacity: np.ndarray,
    color: str,
    dash: tuple[float, ...],
) -> str:
    """A stroke whose opacity varies: a group of stroked paths, one per run of segments of
    one opacity (the mean of the segment's ends, in steps of 1/32); transparent runs left
    out."""
    n = len(s)
    ends = np.arange(n) if s.closed else np.arange(n - 1)
    nxt = (ends + 1) % n
    level = np.round(0.5 * (opacity[ends] + opacity[nxt]) * OPACITY_STEPS) / OPACITY_STEPS
    out = [f"      <g {attrs}>"]
    start = 0
    for k in range(1, len(ends) + 1):
        if k < len(ends) and level[k] == level[start]:
            continue
        if level[start] > 0:
            idx = np.append(ends[start:k], nxt[k - 1])
            a = f"{level[start]:.4g}"
            body = _stroked(s.points[idx], False, widths[idx], color, dash)
            out.append(f'        <path stroke-opacity="{a}" {body}/>')
        start = k
    out.append("      </g>")
    return "\n".join(out)


#: Characters XML 1.0 cannot hold, not even escaped (object names come from scene files).
_NOT_XML = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ufffe\uffff]")


def _text(s: str) -> str:
    s = _NOT_XML.sub("\ufffd", s)
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def _finite(a: np.ndarray | None) -> Any:
    """A nested list with non-finite numbers as ``None``."""
    if a is None:
        return None
    return [
        _finite(x) if isinstance(x, np.ndarray) else (float(x) if math.isfinite(x) else None)
        for x in a
    ]


def stroke_json(drawing: StrokeDrawing) -> str:
    """The JSON text of a :class:`~mi_npr.strokes.drawing.StrokeDrawing` (module docstring)."""
    st, style = drawing.strokes, drawing.style
    rows = []
    for i, s in enumerate(st.strokes):
        rows.append(
            {
                "id": i,
                "kind": s.kind,
                "object_id": int(s.object_id[0]),
                "object": st.name_of(int(s.object_id[0])),
                "qi": int(s.qi),
                "visible": s.qi == 0,
                "through_glass": bool(s.through_glass),
                "closed": bool(s.closed),
                "drawn": style.drawn(s),
                "points": _finite(s.points),
                "position": _finite(s.position),
                "depth": _finite(s.depth),
                "depth_behind": _finite(s.depth_behind),
                "object_ids": [int(v) for v in s.object_id],
                "prims": [int(v) for v in s.prim],
                "width": _finite(style.widths(s, st.depth_range)),
                "opacity": _finite(style.opacity(s, st.depth_range)),
            }
        )
    doc = {
        "format": "mi-npr-strokes",
        "version": 1,
        "width": st.width,
        "height": st.height,
        "camera": st.camera.to_dict() if st.camera is not None else None,
        "depth_range": _finite(np.asarray(st.depth_range, np.float64)),
        "params": dict(st.params),
        "style": style.to_dict(),
        "kinds": list(KINDS),
        "objects": {str(k): v for k, v in sorted(st.objects.items())},
        "strokes": rows,
    }
    return json.dumps(doc, allow_nan=False, separators=(",", ":")) + "\n"


def strokes_on_paper(drawing: StrokeDrawing, paper: Any = PAPER) -> np.ndarray:
    """The drawn strokes on ``paper`` (linear RGB): (H, W, 3), the picture of
    ``<stem>_strokes.png``."""
    return on_background(drawing.alpha, drawing.ink, paper)


def stroke_files(
    drawing: StrokeDrawing, stem: str, title: str | None = None
) -> list[tuple[str, Any]]:
    """``(file name, content)`` of the three files: SVG and JSON text, the PNG's image."""
    return [
        (f"{stem}_strokes.svg", stroke_svg(drawing, title)),
        (f"{stem}_strokes.json", stroke_json(drawing)),
        (f"{stem}_strokes.png", strokes_on_paper(drawing)),
    ]


def write_strokes(
    drawing: StrokeDrawing, outdir: str | os.PathLike[str], stem: str, title: str | None = None
) -> list[Path]:
    """Write ``<stem>_strokes.svg``, ``.json`` and ``.png`` into ``outdir``, all or none."""
    d = check_writable_dir(outdir, create=True)
    files = stroke_files(drawing, stem, title)
    out = []
    with output_set():
        for name, data in files:
            if isinstance(data, str):
                out.append(write_text(d / name, data))
            else:
                out.append(write_png(d / name, data))
    return out
