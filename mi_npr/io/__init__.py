"""Everything that touches files: EXR (all layers), PNG (beauty, overlays). Kernels never do."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from .. import layers as L
from ..gbuffer import GBuffer
from ._atomic import atomic_output, check_writable_dir, output_set
from .exr import describe, read_exr, write_exr
from .png import linear_to_srgb, to_rgb8, write_png
from .svg import svg_document, write_contour_outputs, write_svg
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
    from ..drawing import INK, PAPER, drawing

    d = check_writable_dir(outdir, create=True)
    sheet = None
    if L.LINES in gb:
        sheet = drawing(gb, INK if line_color is None else line_color, paper or PAPER)
    with output_set():  # all or none
        out = [write_exr(d / f"{stem}.exr", gb), write_png(d / f"{stem}.png", gb.beauty)]
        if sheet is not None:
            out.append(write_png(d / f"{stem}_lines.png", sheet))
    return out


def write_raytree_outputs(
    gb: GBuffer, outdir: str | os.PathLike[str], stem: str, strokes: Mapping[str, Any]
) -> list[Path]:
    """What ``mi-npr raytree`` writes: ``<stem>.exr``, ``<stem>_raytree.png`` (the edge classes
    over the beauty) and ``<stem>_raytree.svg`` (each class an Inkscape layer of paths from
    ``strokes``, over the raw beauty embedded once)."""
    from ..compose import raw_beauty

    d = check_writable_dir(outdir, create=True)
    with output_set():  # every file together, or none of them
        return [
            write_exr(d / f"{stem}.exr", gb),
            write_png(d / f"{stem}_raytree.png", gb.beauty),
            write_svg(
                d / f"{stem}_raytree.svg",
                [],
                gb.width,
                gb.height,
                beauty=raw_beauty(gb),
                strokes=strokes,
                title=gb.metadata.get("mi_npr/scene", stem),
            ),
        ]


__all__ = [
    "atomic_output",
    "check_writable_dir",
    "describe",
    "linear_to_srgb",
    "output_set",
    "read_exr",
    "svg_document",
    "to_rgb8",
    "write_contour_outputs",
    "write_exr",
    "write_outputs",
    "write_png",
    "write_raytree_outputs",
    "write_svg",
    "write_text",
]
