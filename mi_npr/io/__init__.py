"""Everything that touches files: EXR (all layers), PNG (beauty, overlays). Kernels never do."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..gbuffer import GBuffer
from ._atomic import atomic_output, check_writable_dir
from .exr import describe, read_exr, write_exr
from .png import linear_to_srgb, to_rgb8, write_png
from .svg import svg_document, write_contour_outputs, write_svg
from .text import write_text


def write_outputs(gb: GBuffer, outdir: str | os.PathLike[str], stem: str) -> list[Path]:
    """``outdir/<stem>.exr`` (every layer) and ``outdir/<stem>.png`` (the beauty, sRGB)."""
    d = check_writable_dir(outdir, create=True)
    return [write_exr(d / f"{stem}.exr", gb), write_png(d / f"{stem}.png", gb.beauty)]


def write_raytree_outputs(
    gb: GBuffer, outdir: str | os.PathLike[str], stem: str, strokes: Mapping[str, Any]
) -> list[Path]:
    """What ``mi-npr raytree`` writes: ``<stem>.exr``, ``<stem>_raytree.png`` (the edge classes
    over the beauty) and ``<stem>_raytree.svg`` (each class an Inkscape layer of paths from
    ``strokes``, over the raw beauty embedded once)."""
    from ..compose import raw_beauty

    d = check_writable_dir(outdir, create=True)
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
