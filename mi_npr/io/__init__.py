"""Everything that touches files: EXR (all layers), PNG (beauty, overlays). Kernels never do."""

from __future__ import annotations

import functools
import os
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from .. import layers as L
from ..compose import INK, PAPER, lines_on_paper, raw_beauty
from ..errors import ParameterError
from ..gbuffer import GBuffer
from ..strokes.drawing import StrokeDrawing
from ._atomic import atomic_output, check_writable_dir, output_set
from .exr import ExrImage, describe, exr_image, read_exr, write_exr, write_exr_image
from .png import linear_to_srgb, to_rgb8, write_png
from .strokes import stroke_files
from .svg import SVG_IMAGE, svg_document, write_contour_outputs, write_svg
from .text import write_text


def write_outputs(
    gb: GBuffer,
    outdir: str | os.PathLike[str],
    stem: str,
    line_color: Sequence[float] | None = None,
    paper: Sequence[float] | None = None,
) -> list[Path]:
    """``outdir/<stem>.exr`` (every layer), ``outdir/<stem>.png`` (the beauty, sRGB) and, when
    ``gb`` has a ``lines`` layer, ``outdir/<stem>_lines.png``: the drawing alone,
    ``line_color`` ink (default black) on ``paper`` (default white), linear RGB. Each file is
    written under a temporary name and renamed when complete; the drawing is computed before
    any file is written, so bad colours leave no output."""
    d = check_writable_dir(outdir, create=True)
    sheet = None
    if L.LINES in gb:
        sheet = lines_on_paper(gb, INK if line_color is None else line_color, paper or PAPER)
    with output_set():  # all or none
        out = [write_exr(d / f"{stem}.exr", gb), write_png(d / f"{stem}.png", gb.beauty)]
        if sheet is not None:
            out.append(write_png(d / f"{stem}_lines.png", sheet))
    return out


def write_layered_outputs(
    result: Any,
    outdir: str | os.PathLike[str],
    stem: str,
    *,
    only: str | None = None,
    line_color: Sequence[float] | None = None,
    paper: Sequence[float] | None = None,
    svg_image: str = "embed",
) -> list[Path]:
    """The files of a :class:`~mi_npr.pipeline.LayeredRender`, in ``outdir``:

    - ``<stem>.exr`` (every layer) and ``<stem>.png`` (the beauty, with the lines if drawn);
    - one picture per drawing: ``<stem>_lines.png`` (the lines alone, ``line_color`` ink on
      ``paper``) with ``<stem>_lines.svg`` (its strokes), ``<stem>_contours.png`` with
      ``<stem>_contours.svg`` (vector contours on the true outline; none with the ``soft``
      ``contour_model``, whose contours are a raster ink layer), ``<stem>_raytree.png``
      with ``<stem>_raytree.svg`` (one Inkscape layer per edge class), and for the ``strokes``
      drawing ``<stem>_strokes.svg``, ``<stem>_strokes.json`` and ``<stem>_strokes.png``
      (:mod:`mi_npr.io.strokes`).

    ``svg_image``: the raw beauty under the SVG drawings: ``embed`` (once), ``link`` (written
    as ``<stem>_beauty.png``) or ``none``. ``only="contours"`` (or ``"raytree"``) writes what
    the ``contours`` (``raytree``) command writes: that drawing's files, its EXR named
    ``<stem>_contours.exr`` (``_raytree``) with ``R G B`` holding the drawing, so the shorthands
    never overwrite ``render``'s files. Every file is written under a temporary name before
    the first is renamed into place: they are replaced all together or not at all
    (:func:`output_set`). The same as :func:`write_files` of :func:`layered_files`.
    """
    d = check_writable_dir(outdir, create=True)
    files = layered_files(
        result, d, stem, only=only, line_color=line_color, paper=paper, svg_image=svg_image
    )
    return write_files(d, files)


#: What :func:`write_files` writes for a file: an :class:`ExrImage` (EXR), a float or 8-bit
#: image array (PNG), a text, or a function of no arguments that returns the text.
FileData = Any


def layered_files(
    result: Any,
    outdir: str | os.PathLike[str],
    stem: str,
    *,
    only: str | None = None,
    line_color: Sequence[float] | None = None,
    paper: Sequence[float] | None = None,
    svg_image: str = "embed",
) -> list[tuple[str, FileData]]:
    """The files of :func:`write_layered_outputs` as ``(name, data)`` (:data:`FileData`), taken
    out of the render: numpy arrays and texts, nothing of Dr.Jit's, so that they can be encoded
    and written in another thread (the SVG texts are built there, from numpy arrays).
    ``outdir`` names the files in errors."""

    if svg_image not in SVG_IMAGE:
        raise ParameterError(f"svg_image = {svg_image!r}: must be one of {', '.join(SVG_IMAGE)}")
    gb = result.gbuffer
    files: list[tuple[str, Any]] = []
    if only is not None:
        name = f"{stem}_{only}.exr"
        files.append((name, exr_image(Path(outdir) / name, result.drawing(only))))
        files.append((f"{stem}_{only}.png", result.pictures[only]))
    else:
        exr = exr_image(Path(outdir) / f"{stem}.exr", gb)
        files += [(f"{stem}.exr", exr), (f"{stem}.png", gb.beauty)]
        if L.LINES in gb:
            sheet = lines_on_paper(gb, INK if line_color is None else line_color, paper or PAPER)
            files.append((f"{stem}_lines.png", sheet))
        for name in ("contours", "raytree"):
            if name in result.pictures:
                files.append((f"{stem}_{name}.png", result.pictures[name]))
        drawing = getattr(result, "vector_strokes", None)
        if drawing is not None:  # the strokes drawing: SVG, JSON and ink on paper
            files += stroke_files(drawing, stem, gb.metadata.get("mi_npr/scene", stem))
    image: dict[str, Any] = {}
    drawn = [n for n in ("lines", "contours", "raytree") if only in (None, n)]
    strokes = result.strokes or {}
    wanted = {
        "lines": ([], {k: v for k, v in strokes.items() if k == L.LINES.split(".")[0]}),
        "contours": (result.paths or result.contours, {}),
        "raytree": ([], {k: v for k, v in strokes.items() if k.startswith("edges")}),
    }
    present = {
        "lines": L.LINES in gb,
        # the soft contour model's contours are a raster ink layer: no vector contours
        "contours": "contours" in result.pictures and L.CONTOUR_INK not in gb,
        "raytree": "raytree" in result.pictures,
    }
    if svg_image == "embed":
        image["beauty"] = raw_beauty(gb)
    elif svg_image == "link" and any(present[n] for n in drawn):
        files.append((f"{stem}_beauty.png", raw_beauty(gb)))
        image["beauty_href"] = f"{stem}_beauty.png"
    meta = gb.metadata
    color = tuple(float(v) for v in meta.get("mi_npr/contour_color", "1,0,0").split(","))
    for name in drawn:
        if not present[name]:
            continue
        paths, layers = wanted[name]
        svg = functools.partial(
            svg_document,
            list(paths),
            gb.width,
            gb.height,
            color=color,
            stroke_width=float(meta.get("mi_npr/contour_line_width", "1")),
            title=meta.get("mi_npr/scene", stem),
            strokes=layers,
            **image,
        )
        files.append((f"{stem}_{name}.svg", svg))
    return files


def write_files(
    outdir: str | os.PathLike[str], files: Sequence[tuple[str, FileData]]
) -> list[Path]:
    """Write ``files`` (:func:`layered_files`) into ``outdir`` all together or none of them
    (:func:`output_set`); their paths, in order. The texts given as functions (the SVGs, the
    strokes' JSON: Python, which holds the interpreter's lock) are made on a thread of their
    own while this one encodes and writes the images (OpenEXR's and zlib's work, which lets go
    of it); the files are renamed into place once every one is written."""
    d = Path(outdir)
    out: list[Path | None] = [None] * len(files)
    pool = ThreadPoolExecutor(1, "mi-npr texts") if any(callable(v) for _, v in files) else None
    try:
        made = {i: pool.submit(v) for i, (_, v) in enumerate(files) if callable(v)} if pool else {}
        with output_set():  # every file together, or none of them
            for i, (name, data) in enumerate(files):  # the images, beside the texts
                if isinstance(data, ExrImage):
                    out[i] = write_exr_image(d / name, data)
                elif i not in made and not isinstance(data, str):
                    out[i] = write_png(d / name, data)
            for i, (name, data) in enumerate(files):
                if out[i] is None:
                    out[i] = write_text(d / name, made[i].result() if i in made else data)
    finally:
        if pool is not None:  # a failure: the texts not started are not made
            pool.shutdown(wait=True, cancel_futures=True)
    return [p for p in out if p is not None]


def write_strokes(
    drawing: StrokeDrawing, outdir: str | os.PathLike[str], stem: str, title: str | None = None
) -> list[Path]:
    """Write a stroke drawing's ``<stem>_strokes.svg``,
    ``.json`` and ``.png`` (:func:`mi_npr.io.strokes.stroke_files`) into ``outdir``, all or
    none (:func:`write_files`)."""
    return write_files(check_writable_dir(outdir, create=True), stroke_files(drawing, stem, title))


__all__ = [
    "ExrImage",
    "atomic_output",
    "check_writable_dir",
    "describe",
    "exr_image",
    "layered_files",
    "linear_to_srgb",
    "output_set",
    "read_exr",
    "svg_document",
    "to_rgb8",
    "write_contour_outputs",
    "write_exr",
    "write_exr_image",
    "write_files",
    "write_layered_outputs",
    "write_outputs",
    "write_png",
    "write_strokes",
    "write_svg",
    "write_text",
]
