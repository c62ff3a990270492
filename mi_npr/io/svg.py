"""SVG output of contours: vector lines a browser, Inkscape or Illustrator opens and restyles.

Layout of the document (``width`` x ``height`` user units = pixels, y down like the image)::

    <svg viewBox="0 0 W H">
      <image id="beauty" .../>                    optional: the beauty render, base64 PNG (sRGB)
      <g id="contours" fill="none" stroke="#ff0000" stroke-width="1" ...>
        <g id="sphere_left" data-object-id="3" data-name="sphere_left" fill-rule="evenodd">
          <path class="outer" d="M 10.5 3.5 L 11.5 3.5 ... Z"/>
          <path class="hole" fill-rule="evenodd" d="..."/>
        </g>
        ...

One ``<path>`` per contour through the centres of its pixels (``x + 0.5, y + 0.5``), closed with
``Z`` when the contour is closed, one ``<g>`` per object. Group ids are the object names made
into valid XML names (characters other than letters, digits, ``_ . -`` become ``_``, a leading
digit gets a ``_`` prefix, a clash gets ``-<object id>``); ``data-name`` keeps the exact name.
Holes carry ``fill-rule="evenodd"`` (inherited from their group too), so giving a group a fill
(or combining its paths into one) leaves the holes empty. Writes are atomic.
"""

from __future__ import annotations

import base64
import io
import os
import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np
from PIL import Image

from ..errors import ParameterError
from ..gbuffer import GBuffer
from ._atomic import atomic_output, check_writable_dir
from .png import linear_to_srgb, to_rgb8

_RESERVED = {"beauty", "contours"}


def _hex(color: Sequence[float]) -> str:
    c = np.asarray(color, dtype=np.float32).reshape(-1)
    if c.size != 3:
        raise ParameterError(f"color {tuple(color)!r} is not an RGB triple")
    s = (linear_to_srgb(c) * 255.0 + 0.5).astype(np.uint8)
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


def _path_data(points: np.ndarray, closed: bool) -> str:
    p = np.asarray(points, np.int64)
    if len(p) == 0:
        return ""
    coords = [f"{x}.5 {y}.5" for x, y in p.tolist()]
    d = "M " + coords[0]
    if len(coords) > 1:
        d += " L " + " ".join(coords[1:])
    return d + (" Z" if closed else "")


def _png_base64(image: np.ndarray) -> str:
    buf = io.BytesIO()
    Image.fromarray(to_rgb8(np.asarray(image)[..., :3])).save(buf, format="PNG")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def svg_document(
    contours: Iterable,
    width: int,
    height: int,
    *,
    beauty: np.ndarray | None = None,
    color: Sequence[float] = (1.0, 0.0, 0.0),
    stroke_width: float = 1.0,
    title: str | None = None,
) -> str:
    """The SVG text for ``contours`` (:class:`~mi_npr.contours.Contour`) over an image of
    ``width`` x ``height`` pixels; ``beauty`` ((H, W, 3) linear RGB) is embedded beneath them.
    ``color`` is linear RGB (written as sRGB hex)."""
    w, h = int(width), int(height)
    if w < 1 or h < 1:
        raise ParameterError(f"SVG size {width} x {height}: must be positive")
    groups: dict[int, tuple[str, list[str]]] = {}
    for c in contours:
        d = _path_data(c.points, c.closed)
        if not d:
            continue
        kind = ' class="hole" fill-rule="evenodd"' if c.is_hole else ' class="outer"'
        groups.setdefault(c.object_id, (c.name, []))[1].append(f'    <path{kind} d="{d}"/>')
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" '
        f'version="1.1" width="{w}" height="{h}" viewBox="0 0 {w} {h}">',
    ]
    if title:
        out.append(f"<title>{_text(title)}</title>")
    if beauty is not None:
        b = np.asarray(beauty)
        if b.ndim != 3 or b.shape[:2] != (h, w) or b.shape[-1] < 3:
            raise ParameterError(f"SVG beauty: shape {b.shape} does not match {w} x {h}")
        data = "data:image/png;base64," + _png_base64(b)
        out.append(
            f'<image id="beauty" x="0" y="0" width="{w}" height="{h}" '
            f'style="image-rendering:pixelated" href="{data}" xlink:href="{data}"/>'
        )
    out.append(
        f'<g id="contours" fill="none" stroke="{_hex(color)}" stroke-width="{stroke_width:g}" '
        'stroke-linejoin="round" stroke-linecap="round">'
    )
    taken: set[str] = set()
    for k in sorted(groups):
        name, paths = groups[k]
        gid = xml_id(name, taken, str(k))
        out.append(
            f'  <g id={quoteattr(gid)} data-object-id="{k}" data-name={quoteattr(_xml_safe(name))} '
            'fill-rule="evenodd">'
        )
        out.extend(paths)
        out.append("  </g>")
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
    text = svg_document(contours, width, height, **options)
    target = Path(path)
    with atomic_output(target) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return target


def write_contour_outputs(
    gb: GBuffer,
    contours: Iterable,
    outdir: str | os.PathLike[str],
    stem: str,
    *,
    beauty_in_svg: bool = True,
) -> list[Path]:
    """What ``mi-npr contours`` writes: ``<stem>_contours.exr`` (every layer, ``contour``
    included),
    ``<stem>_contours.png`` (R G B: the beauty with the contours drawn) and
    ``<stem>_contours.svg`` (the contours as paths, over the raw beauty unless
    ``beauty_in_svg=False``), in ``outdir``. The SVG's colour is the GBuffer's
    ``mi_npr/contour_color`` (red if absent)."""
    from ..compose import raw_beauty
    from .exr import write_exr
    from .png import write_png

    d = check_writable_dir(outdir, create=True)
    try:
        color = tuple(float(v) for v in gb.metadata["mi_npr/contour_color"].split(","))
    except (KeyError, ValueError):
        color = (1.0, 0.0, 0.0)
    svg = write_svg(
        d / f"{stem}_contours.svg",
        list(contours),
        gb.width,
        gb.height,
        beauty=raw_beauty(gb) if beauty_in_svg else None,
        color=color,
        title=gb.metadata.get("mi_npr/scene", stem),
    )
    return [
        write_exr(d / f"{stem}_contours.exr", gb),
        write_png(d / f"{stem}_contours.png", gb.beauty),
        svg,
    ]
