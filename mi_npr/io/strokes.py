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
(0.0005 px). No raster image is embedded. The document is written by
:func:`mi_npr.io.svg.svg_document` (a :class:`~mi_npr.io.svg.StrokeLayer`), the writer of every
SVG, so the ``lines`` drawing's ``<stem>_lines.svg`` holds its strokes the same way.

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

import functools
import json
from typing import Any

import numpy as np
import orjson

from ..compose import PAPER
from ..strokes.drawing import StrokeDrawing
from ..strokes.model import KINDS
from ..strokes.raster import on_background
from .svg import StrokeLayer, style_arrays, svg_document


def stroke_svg(drawing: StrokeDrawing, title: str | None = None) -> str:
    """The SVG text of a :class:`~mi_npr.strokes.drawing.StrokeDrawing` (module docstring):
    :func:`mi_npr.io.svg.svg_document` with one :class:`~mi_npr.io.svg.StrokeLayer`."""
    st = drawing.strokes
    layer = StrokeLayer(st, drawing.style)
    return svg_document([], st.width, st.height, title=title, strokes={"strokes": layer})


def _finite(a: np.ndarray | None) -> Any:
    """A nested list of floats with the non-finite numbers as ``None``: one ``tolist`` of the
    array as float64 (the values of ``float(x)`` element by element), ``None`` put in at the
    non-finite places only."""
    if a is None:
        return None
    a = np.asarray(a, np.float64)
    out = a.tolist()
    bad = ~np.isfinite(a)
    if bad.any():
        for index in zip(*np.nonzero(bad), strict=True):
            row = out
            for i in index[:-1]:
                row = row[i]
            row[index[-1]] = None
    return out


#: Strokes whose JSON rows are made at once (memory: the block's rows, then its text).
JSON_BLOCK = 1024


def _numbers(a: np.ndarray | None, shape: tuple[int, ...] = ()) -> np.ndarray | None:
    """``a`` as a contiguous float64 array (what orjson writes as nested lists of numbers,
    the non-finite ones as ``null``), or ``None``."""
    if a is None:
        return None
    if (
        type(a) is np.ndarray
        and a.dtype == np.float64
        and a.shape[1:] == shape
        and a.ndim == 1 + len(shape)
        and a.flags.c_contiguous
    ):
        return a  # as it is (most are): no three numpy calls a field a stroke
    return np.ascontiguousarray(np.asarray(a, np.float64).reshape(-1, *shape))


def _json_rows(drawing: StrokeDrawing, first: int, widths: Any, opacity: Any, ends: Any) -> bytes:
    """The JSON text of the rows of the strokes ``first`` to ``first + len(ends)`` (``widths``,
    ``opacity``: their vertices'; ``ends``: where each one's end, counted from the first),
    joined by commas (orjson: numpy arrays written directly, each number the shortest text that
    reads back as the same float64)."""
    st, style = drawing.strokes, drawing.style
    strokes = st.strokes[first : first + len(ends)]
    bounds = [0, *np.asarray(ends).tolist()]
    rows = []
    for i, s in enumerate(strokes):
        oid = np.ascontiguousarray(s.object_id, np.int64)
        a, b = bounds[i], bounds[i + 1]
        rows.append(
            {
                "id": first + i,
                "kind": s.kind,
                "object_id": int(oid[0]),
                "object": st.name_of(int(oid[0])),
                "qi": int(s.qi),
                "visible": bool(s.qi == 0),
                "through_glass": bool(s.through_glass),
                "closed": bool(s.closed),
                "drawn": bool(style.drawn(s)),
                "points": _numbers(s.points, (2,)),
                "position": _numbers(s.position, (3,)),
                "depth": _numbers(s.depth),
                "depth_behind": _numbers(s.depth_behind),
                "object_ids": oid,
                "prims": np.ascontiguousarray(s.prim, np.int64),
                "width": _numbers(widths[a:b]),
                "opacity": _numbers(opacity[a:b]),
            }
        )
    return orjson.dumps(rows, option=orjson.OPT_SERIALIZE_NUMPY)[1:-1]


def stroke_json(drawing: StrokeDrawing) -> str:
    """The JSON text of a :class:`~mi_npr.strokes.drawing.StrokeDrawing` (module docstring),
    made :data:`JSON_BLOCK` strokes at a time."""
    st, style = drawing.strokes, drawing.style
    strokes = st.strokes
    widths, opacity, ends = style_arrays(strokes, style, st.depth_range)
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
    }
    head = json.dumps(doc, allow_nan=False, separators=(",", ":"))
    pieces = [head[:-1].encode(), b',"strokes":[']
    for b in range(0, len(strokes), JSON_BLOCK):
        e = ends[b : b + JSON_BLOCK]
        start = int(ends[b - 1]) if b else 0
        stop = int(e[-1])
        pieces += [b","] if b else []
        pieces.append(_json_rows(drawing, b, widths[start:stop], opacity[start:stop], e - start))
    return b"".join([*pieces, b"]}\n"]).decode()


def strokes_on_paper(drawing: StrokeDrawing, paper: Any = PAPER) -> np.ndarray:
    """The drawn strokes on ``paper`` (linear RGB): (H, W, 3), the picture of
    ``<stem>_strokes.png``."""
    return on_background(drawing.alpha, drawing.ink, paper)


def stroke_files(
    drawing: StrokeDrawing, stem: str, title: str | None = None
) -> list[tuple[str, Any]]:
    """``(file name, content)`` of the three files: the functions that make the SVG and the
    JSON text (made where they are written, :func:`mi_npr.io.write_files`), the PNG's image."""
    return [
        (f"{stem}_strokes.svg", functools.partial(stroke_svg, drawing, title)),
        (f"{stem}_strokes.json", functools.partial(stroke_json, drawing)),
        (f"{stem}_strokes.png", strokes_on_paper(drawing)),
    ]
