"""SVG output of contours: vector lines a browser, Inkscape or Illustrator opens and restyles.

Layout of the document (``width`` x ``height`` user units = pixels, y down like the image)::

    <svg viewBox="0 0 W H" xmlns:inkscape="...">
      <g id="beauty-layer" inkscape:groupmode="layer" inkscape:label="beauty">   optional
        <image id="beauty" href="data:image/png;base64,..."/>   embedded once, or a linked file
      </g>
      <g id="contours" inkscape:groupmode="layer" inkscape:label="contours" fill="none"
         stroke="#ff0000" stroke-width="1" ...>
        <g id="sphere_left" inkscape:label="sphere_left" data-object-id="3"
           data-name="sphere_left" fill-rule="evenodd">
          <path class="outer" d="M 10.52 3.5 L 11.5 3.38 ... Z"/>
          <path class="hole" fill-rule="evenodd" d="..."/>
        </g>
        ...
      </g>
      <g id="edges_real" inkscape:groupmode="layer" inkscape:label="edges_real"
         stroke="#..." ...>                   optional: paths traced from a mask
        <path d="M ... L ..."/> ...
      </g>
      <g id="lines" inkscape:groupmode="layer" inkscape:label="lines" fill="none" ...>
        <g id="silhouette" inkscape:groupmode="layer" data-kind="silhouette">   a StrokeLayer
          <g id="silhouette.box" inkscape:label="box" data-object-id="1" data-name="box">
            <path class="visible" data-stroke="0" data-qi="0" stroke="#000000"
                  stroke-width="1" d="M 10.521 3.5 L ..."/>
          </g>
        </g>
        <g id="traced" inkscape:groupmode="layer" data-source="image" stroke="#000000" ...>
          <path d="..."/>                     lines of the image that no stroke explains
        </g>
      </g>

Every drawing is an Inkscape layer (``inkscape:groupmode="layer"``; other programs see plain
groups), every object a group named after it. A contour is one ``<path>``: either a
:class:`~mi_npr.contours.vector.VectorPath` (vertices on the object's true outline, open where
the object meets the image frame) or a pixel :class:`~mi_npr.contours.Contour` (through its
pixels' centres ``x + 0.5, y + 0.5``), closed with ``Z`` when closed. Coordinates are written
with at most 2 decimals (0.005 px). Group ids are the object names made into valid XML names
(characters other than letters, digits, ``_ . -`` become ``_``, a leading digit gets a ``_``
prefix, a clash gets ``-<object id>``); ``data-name`` and ``inkscape:label`` keep the exact name.
Holes carry ``fill-rule="evenodd"`` (inherited from their group too), so giving a group a fill
(or combining its paths into one) leaves the holes empty. The beauty is either embedded once
as ``xlink:href``, which Inkscape 1.2 reads where it ignores SVG 2's ``href`` (browsers read
both; the data is not written twice), linked (``beauty_href``, a file
beside the SVG, named by ``xlink:href`` and ``href`` both) or left out. Writes are atomic.

Layers of lines come after the contours, one per entry of ``strokes``: paths traced from a mask
(:func:`mi_npr.contours.trace_strokes`, the ray-tree edge classes) in one colour, or a
:class:`StrokeLayer` of object-space strokes (:mod:`mi_npr.strokes`): one sub-layer per edge
kind, one group per object, one element per stroke in its style, coordinates with 3 decimals,
as :mod:`mi_npr.io.strokes` documents for ``<stem>_strokes.svg``, which is written here too.
"""

from __future__ import annotations

import base64
import functools
import io
import os
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..compose import raw_beauty
from ..errors import ParameterError, as_path
from ..gbuffer import GBuffer
from ..params import MAX_RES, Param, check_arg, integer_range, real_range, rgb_color
from ..strokes.model import KINDS, Stroke, Strokes, sizes
from ..strokes.outlines import normals_2d
from ..strokes.style import Style
from ._atomic import atomic_output, check_writable_dir, output_set
from .exr import write_exr
from .png import linear_to_srgb, save_png, to_rgb8, write_png
from .text import quoteattr

_RESERVED = {"beauty", "beauty-layer", "contours"}
_INKSCAPE = "http://www.inkscape.org/namespaces/inkscape"
_XLINK = "http://www.w3.org/1999/xlink"


_WIDTH = Param("width", int, 1, "image width in pixels", integer_range(1, MAX_RES))
_HEIGHT = Param("height", int, 1, "image height in pixels", integer_range(1, MAX_RES))
_COLOR = Param("color", tuple, (1.0, 0.0, 0.0), "linear RGB of the contours", rgb_color)
_STROKE = Param("stroke_width", float, 1.0, "line width", real_range(0.0, 1e4, open_lo=True))
_TITLE = Param("title", str, None, "the SVG's <title>")
_HREF = Param("beauty_href", str, None, "file name or URL of the linked beauty")
_STEM = Param("stem", str, None, "the output files' stem", lambda v: None if v else "is empty")


def _hex(color: Sequence[float]) -> str:
    c = np.asarray(color, dtype=np.float32).reshape(-1)
    if c.size != 3:
        raise ParameterError(f"color {tuple(color)!r} is not an RGB triple")
    return _srgb_hex(c.tobytes())


@functools.lru_cache(maxsize=1024)
def _srgb_hex(rgb: bytes) -> str:
    """``#rrggbb`` of three float32 (their bytes): cached, as every stroke of a drawing asks
    for one of its few colours."""
    s = (linear_to_srgb(np.frombuffer(rgb, np.float32)) * 255.0 + 0.5).astype(np.uint8)
    return "#" + "".join(f"{v:02x}" for v in s)


def xml_id(name: str, taken: set[str], fallback: str) -> str:
    """``name`` as a valid, unused XML id (added to ``taken``)."""
    s = re.sub(r"[^A-Za-z0-9_.-]", "_", name) or "_"
    if not re.match(r"[A-Za-z_]", s):
        s = "_" + s
    if s in taken or s in _RESERVED:
        s = f"{s}-{fallback}"
    while s in taken:
        s += "_"
    taken.add(s)
    return s


def _num(v: float, digits: int = 2) -> str:
    t = f"{v:.{digits}f}".rstrip("0").rstrip(".")
    return "0" if t in ("-0", "") else t


#: A number's trailing zeros after the point (and the point, with none left), in a text of
#: numbers formatted ``%.Nf`` (N >= 1) and separated by spaces ...
_TRAILING = re.compile(r"\.?0+(?= |$)")
#: ... and a negative zero left by them.
_MINUS_ZERO = re.compile(r"(?<!\S)-0(?!\S)")


def _polyline(points: np.ndarray, closed: bool, digits: int = 2) -> str:
    """``M x y L x y ... [Z]``, every number as :func:`_num` writes it: formatted all at once
    (one ``%`` of a template), then trimmed by two regular expressions over the whole text."""
    if len(points) == 0:
        return ""
    flat = np.asarray(points, np.float64).reshape(-1).tolist()
    pair = f"%.{digits}f %.{digits}f"
    text = "M " + pair
    if len(flat) > 2:
        text += " L " + " ".join([pair] * (len(flat) // 2 - 1))
    text = _TRAILING.sub("", text % tuple(flat))
    if "-0" in text:
        text = _MINUS_ZERO.sub("0", text)
    return text + (" Z" if closed else "")


def _path_data(contour: Any) -> str:
    """A contour's ``d``: a vector path's own points, or a pixel contour's pixel centres."""
    pts = np.asarray(contour.points)
    if pts.dtype.kind in "iu":
        pts = pts.astype(np.float64) + 0.5
    return _polyline(pts, contour.closed)


def _png_base64(image: np.ndarray) -> str:
    buf = io.BytesIO()
    save_png(to_rgb8(np.asarray(image)[..., :3]), buf)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _layer(gid: str, label: str, attrs: str = "") -> str:
    return (
        f'<g id={quoteattr(gid)} inkscape:groupmode="layer" inkscape:label={quoteattr(label)}'
        + (f" {attrs}" if attrs else "")
        + ">"
    )


#: Opacity levels of the SVG paths of a stroke whose opacity varies along it.
OPACITY_STEPS = 32
#: Decimals of a stroke's coordinates (0.0005 px).
STROKE_DIGITS = 3


@dataclass(frozen=True)
class StrokeLayer:
    """Object-space strokes as one layer of :func:`svg_document` (module docstring).

    ``strokes`` are drawn in ``style`` (those :meth:`~mi_npr.strokes.style.Style.drawn` keeps;
    one transparent everywhere is left out); ``traced``: polylines traced from the drawing's
    image where it has lines that no stroke draws (:func:`mi_npr.contours.trace_strokes`),
    written in the style's colour and width as one more sub-layer, ``traced``."""

    strokes: Strokes
    style: Style
    traced: Sequence[np.ndarray] = ()


def outline_path(stroke: Stroke, widths: np.ndarray) -> str:
    """The ``d`` of a variable-width stroke's filled outline (module docstring)."""
    n = normals_2d(stroke.points, stroke.closed)
    half = (np.asarray(widths, np.float64) / 2.0)[:, None]
    left, right = stroke.points + n * half, stroke.points - n * half
    if stroke.closed:
        ring = _polyline(left, True, STROKE_DIGITS) + " "
        return ring + _polyline(right[::-1], True, STROKE_DIGITS)
    return _polyline(np.concatenate([left, right[::-1]]), True, STROKE_DIGITS)


def style_arrays(
    strokes: Sequence[Stroke], style: Style, depth_range: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The widths and the opacities ``style`` gives the vertices of ``strokes``
    (:meth:`~mi_npr.strokes.style.Style.widths`, :meth:`~mi_npr.strokes.style.Style.opacity`),
    one stroke after the other, and where each stroke ends (``ends[k]``, one past its last
    vertex). The same numbers as stroke by stroke, in fewer calls: a vertex's opacity, and its
    width without a taper, are of that vertex alone, so all strokes take one call each; a
    taper's arc lengths are summed along each stroke, so with a taper the widths take a call a
    stroke."""
    size = sizes(strokes)
    ends = np.cumsum(size, dtype=np.int64)
    if not strokes:
        return np.zeros(0), np.zeros(0), ends
    opacity = style.vertex_opacity(strokes, depth_range, size)
    if style.taper > 0:
        widths = np.concatenate([style.widths(s, depth_range) for s in strokes])
    else:
        widths = style.vertex_widths(strokes, depth_range, size)
    return widths, opacity, ends


def _runs(ufunc: np.ufunc, values: np.ndarray, ends: np.ndarray) -> list[float]:
    """``ufunc.reduce`` of each run ``values[ends[k - 1]:ends[k]]`` (an empty run: NaN), in one
    call for all runs."""
    starts = np.concatenate([[0], ends[:-1]]).astype(np.int64)
    out = np.full(len(ends), np.nan)
    full = np.flatnonzero(ends > starts)
    if len(full):
        out[full] = ufunc.reduceat(values, starts[full])
    return out.tolist()


def _stroke_layer(name: str, layer: StrokeLayer, taken: set[str]) -> list[str]:
    """The lines of one :class:`StrokeLayer`: a sub-layer per edge kind (in
    :data:`~mi_npr.strokes.KINDS` order), a group per object (the object of a stroke's first
    vertex), a path per stroke; then the ``traced`` sub-layer."""
    st, style = layer.strokes, layer.style
    out = [_layer(name, name, 'fill="none" stroke-linecap="round" stroke-linejoin="round"')]
    by_kind: dict[str, dict[int, list[str]]] = {}  # kind -> object -> paths, in stroke order
    drawn = [(i, s) for i, s in enumerate(st.strokes) if style.drawn(s)]
    widths, opacity, ends = style_arrays([s for _, s in drawn], style, st.depth_range)
    # each stroke's extremes in a few calls, not a few calls a stroke (np.ptp is max - min;
    # fmax skips NaN as np.any(opacity > 0) does)
    w_hi, w_lo = _runs(np.maximum, widths, ends), _runs(np.minimum, widths, ends)
    o_hi, o_lo = _runs(np.maximum, opacity, ends), _runs(np.minimum, opacity, ends)
    seen = _runs(np.fmax, opacity, ends)
    bounds = np.concatenate([[0], ends]).tolist()
    paint: dict[tuple[str, bool], tuple[str, tuple[float, ...]]] = {}
    for k, (i, s) in enumerate(drawn):
        if not seen[k] > 0:
            continue  # transparent everywhere (eq. 5.1 finds no depth step along it)
        a, b = bounds[k], bounds[k + 1]
        w, o = widths[a:b], opacity[a:b]
        attrs = f'class="{"visible" if s.qi == 0 else "hidden"}" data-stroke="{i}" data-qi="{s.qi}"'
        if s.through_glass:
            attrs += ' data-through-glass="true"'
        look = (s.kind, s.qi > 0)  # what a stroke's colour and dashes depend on
        if look not in paint:
            paint[look] = (_hex(style.kind_color(s)), style.dashes(s))
        color, dash = paint[look]
        if o_hi[k] - o_lo[k] > 1e-9:
            path = _opacity_runs(attrs, s, w, o, color, dash)
        else:
            if o[0] < 1.0:
                attrs += f' stroke-opacity="{o[0]:.4g}" fill-opacity="{o[0]:.4g}"'
            if dash or w_hi[k] - w_lo[k] <= 1e-9 * max(1.0, w_hi[k]):  # stroked
                path = f"      <path {attrs} {_stroked(s.points, s.closed, w, color, dash)}/>"
            else:  # filled outline
                rule = ' fill-rule="evenodd"' if s.closed else ""
                d = outline_path(s, w)
                path = f'      <path {attrs} fill="{color}" stroke="none"{rule} d="{d}"/>'
        by_kind.setdefault(s.kind, {}).setdefault(int(s.object_id[0]), []).append(path)
    for kind in KINDS:
        groups = by_kind.get(kind)
        if not groups:
            continue
        kid = quoteattr(xml_id(kind, taken, name))
        out.append(
            f'  <g id={kid} inkscape:groupmode="layer" inkscape:label="{kind}" data-kind="{kind}">'
        )
        for oid in sorted(groups):
            obj = st.name_of(oid)
            gid = xml_id(f"{kind}.{obj}", taken, str(oid))
            label = quoteattr(_xml_safe(obj))
            out.append(
                f"    <g id={quoteattr(gid)} inkscape:label={label} "
                f'data-object-id="{oid}" data-name={label}>'
            )
            out.extend(groups[oid])
            out.append("    </g>")
        out.append("  </g>")
    traced = [_polyline(p, len(p) == 1, STROKE_DIGITS) for p in layer.traced]
    if any(traced):
        tid = quoteattr(xml_id("traced", taken, name))
        width = _num(style.width, STROKE_DIGITS)
        out.append(
            f'  <g id={tid} inkscape:groupmode="layer" inkscape:label="traced" '
            f'data-source="image" stroke="{_hex(style.color)}" stroke-width="{width}">'
        )
        out.extend(f'    <path d="{d}"/>' for d in traced if d)
        out.append("  </g>")
    out.append("</g>")
    return out


@functools.lru_cache(maxsize=64)
def _dasharray(dash: tuple[float, ...]) -> str:
    """A dash pattern's ``stroke-dasharray`` (cached: a drawing has one or two)."""
    return " ".join(_num(x, STROKE_DIGITS) for x in dash)


def _stroked(
    points: np.ndarray, closed: bool, widths: np.ndarray, color: str, dash: tuple[float, ...]
) -> str:
    extra = f' stroke-dasharray="{_dasharray(dash)}"' if dash else ""
    # np.mean's own sum and division, without its wrapper (called once a stroke)
    width = _num(float(np.add.reduce(widths) / len(widths)), STROKE_DIGITS)
    d = _polyline(points, closed, STROKE_DIGITS)
    return f'stroke="{color}" stroke-width="{width}"{extra} d="{d}"'


def _opacity_runs(
    attrs: str,
    s: Stroke,
    widths: np.ndarray,
    opacity: np.ndarray,
    color: str,
    dash: tuple[float, ...],
) -> str:
    """A stroke whose opacity varies: a group of stroked paths, one per run of segments of
    one opacity (the mean of the segment's ends, in steps of 1/:data:`OPACITY_STEPS`);
    transparent runs left out."""
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


def svg_document(
    contours: Iterable,
    width: int,
    height: int,
    *,
    beauty: np.ndarray | None = None,
    beauty_href: str | None = None,
    color: Sequence[float] = (1.0, 0.0, 0.0),
    stroke_width: float = 1.0,
    title: str | None = None,
    strokes: Mapping[str, StrokeLayer | tuple[Sequence[np.ndarray], Sequence[float]]] | None = None,
) -> str:
    """The SVG text for ``contours`` (:class:`~mi_npr.contours.vector.VectorPath` or
    :class:`~mi_npr.contours.Contour`) over an image of ``width`` x ``height`` pixels.

    ``beauty`` ((H, W, 3) linear RGB) is embedded beneath them as a PNG, or ``beauty_href``
    (a file name or URL) is linked instead. ``strokes`` maps a layer name to a
    :class:`StrokeLayer` (object-space strokes, each in its style) or to (polylines, linear
    RGB colour), paths traced from an image (ray-tree edge classes): one more layer per entry.
    ``color`` is linear RGB (written as sRGB hex)."""
    w = check_arg("write_svg", _WIDTH, width)
    h = check_arg("write_svg", _HEIGHT, height)
    color = check_arg("write_svg", _COLOR, _COLOR.default if color is None else color)
    stroke_width = check_arg(
        "write_svg", _STROKE, _STROKE.default if stroke_width is None else stroke_width
    )
    title = check_arg("write_svg", _TITLE, title)
    beauty_href = check_arg("write_svg", _HREF, beauty_href)
    if beauty is not None and beauty_href is not None:
        raise ParameterError("SVG beauty: give the image (embed) or beauty_href (link), not both")
    groups: dict[int, tuple[str, list[str]]] = {}
    for c in contours:
        d = _path_data(c)
        if not d:
            continue
        kind = ' class="hole" fill-rule="evenodd"' if c.is_hole else ' class="outer"'
        groups.setdefault(c.object_id, (c.name, []))[1].append(f'    <path{kind} d="{d}"/>')
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="{_XLINK}" '
        f'xmlns:inkscape="{_INKSCAPE}" version="1.1" width="{w}" height="{h}" '
        f'viewBox="0 0 {w} {h}">',
    ]
    if title:
        out.append(f"<title>{_text(title)}</title>")
    href = None
    if beauty is not None:
        b = np.asarray(beauty)
        if b.ndim != 3 or b.shape[:2] != (h, w) or b.shape[-1] < 3:
            raise ParameterError(f"SVG beauty: shape {b.shape} does not match {w} x {h}")
        href = "data:image/png;base64," + _png_base64(b)
    elif beauty_href is not None:
        href = _xml_safe(beauty_href)
    if href is not None:
        out.append(_layer("beauty-layer", "beauty"))
        # A data URI once, as xlink:href (what Inkscape 1.2 reads, and browsers too); a link as
        # both attributes.
        both = "" if href.startswith("data:") else f"href={quoteattr(href)} "
        out.append(
            f'  <image id="beauty" x="0" y="0" width="{w}" height="{h}" '
            f'style="image-rendering:pixelated" {both}xlink:href={quoteattr(href)}/>'
        )
        out.append("</g>")
    taken: set[str] = set(strokes or ())
    if groups or not strokes:  # a drawing of strokes only has no empty contours layer
        out.append(
            _layer(
                "contours",
                "contours",
                f'fill="none" stroke="{_hex(color)}" stroke-width="{stroke_width:g}" '
                'stroke-linejoin="round" stroke-linecap="round"',
            )
        )
    for k in sorted(groups):
        name, paths = groups[k]
        gid = xml_id(name, taken, str(k))
        label = quoteattr(_xml_safe(name))
        out.append(
            f'  <g id={quoteattr(gid)} inkscape:label={label} data-object-id="{k}" '
            f'data-name={label} fill-rule="evenodd">'
        )
        out.extend(paths)
        out.append("  </g>")
    if groups or not strokes:
        out.append("</g>")
    for name, entry in (strokes or {}).items():
        if isinstance(entry, StrokeLayer):
            out.extend(_stroke_layer(name, entry, taken))
            continue
        lines, rgb = entry
        out.append(
            _layer(
                name,
                name,
                f'fill="none" stroke="{_hex(rgb)}" stroke-width="{stroke_width:g}" '
                'stroke-linejoin="round" stroke-linecap="round"',
            )
        )
        for line in lines:
            d = _polyline(line, False) if len(line) > 1 else _polyline(line, True)
            if d:
                out.append(f'  <path d="{d}"/>')
        out.append("</g>")
    out.append("</svg>")
    return "\n".join(out) + "\n"


#: Characters XML 1.0 cannot hold at all, not even escaped (control characters, U+FFFE/FFFF).
_NOT_XML = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ufffe\uffff]")


def _xml_safe(s: str) -> str:
    """``s`` without the characters XML cannot hold (each becomes U+FFFD)."""
    return _NOT_XML.sub("\ufffd", s)


def _text(s: str) -> str:
    s = _xml_safe(s)
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def write_svg(
    path: str | os.PathLike[str], contours: Iterable, width: int, height: int, **options: Any
) -> Path:
    """Write :func:`svg_document` (same arguments and keyword ``options``) to ``path``
    (atomically). Returns the path."""
    target = as_path(path, "write_svg: path")
    text = svg_document(contours, width, height, **options)
    with atomic_output(target) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return target


#: How ``write_contour_outputs`` puts the beauty in the SVG (``mi-npr contours --svg-image``).
SVG_IMAGE = ("embed", "link", "none")


def write_contour_outputs(
    gb: GBuffer,
    contours: Iterable,
    outdir: str | os.PathLike[str],
    stem: str,
    *,
    beauty_in_svg: bool = True,
    svg_image: str = "embed",
    paths: Iterable | None = None,
    strokes: Mapping[str, tuple[Sequence[np.ndarray], Sequence[float]]] | None = None,
) -> list[Path]:
    """The files of ``mi-npr contours``: ``<stem>_contours.exr`` (every layer, ``contour.V``
    included), ``<stem>_contours.png`` (R G B: the beauty with the contours drawn) and
    ``<stem>_contours.svg`` (``paths`` if given, else the pixel ``contours``, plus ``strokes``
    layers; the command's SVG holds :func:`mi_npr.contours.vectorize`'s outlines).
    ``svg_image``: ``embed`` the raw beauty in the SVG, ``link`` it (written as
    ``<stem>_beauty.png`` beside it) or ``none`` (also ``beauty_in_svg=False``). The SVG's colour
    is the GBuffer's ``mi_npr/contour_color`` (red if absent)."""

    if svg_image not in SVG_IMAGE:
        raise ParameterError(f"svg_image = {svg_image!r}: must be one of {', '.join(SVG_IMAGE)}")
    if stem is None or check_arg("write_contour_outputs", _STEM, stem) is None:
        raise ParameterError("write_contour_outputs: parameter 'stem' = None: expected a string")
    if not beauty_in_svg:
        svg_image = "none"
    d = check_writable_dir(outdir, create=True)
    try:
        color = tuple(float(v) for v in gb.metadata["mi_npr/contour_color"].split(","))
    except (KeyError, ValueError):
        color = (1.0, 0.0, 0.0)
    with output_set():  # every file together, or none of them
        written = [
            write_exr(d / f"{stem}_contours.exr", gb),
            write_png(d / f"{stem}_contours.png", gb.beauty),
        ]
        image: dict[str, Any] = {}
        if svg_image == "embed":
            image["beauty"] = raw_beauty(gb)
        elif svg_image == "link":
            linked = write_png(d / f"{stem}_beauty.png", raw_beauty(gb))
            written.append(linked)
            image["beauty_href"] = linked.name
        svg = write_svg(
            d / f"{stem}_contours.svg",
            list(paths if paths is not None else contours),
            gb.width,
            gb.height,
            color=color,
            title=gb.metadata.get("mi_npr/scene", stem),
            strokes=strokes,
            **image,
        )
        return [*written, svg]
