"""Everything that touches files: EXR (all layers), PNG (beauty, overlays). Kernels never do."""

from __future__ import annotations

import os
from pathlib import Path

from ..gbuffer import GBuffer
from ._atomic import atomic_output, check_writable_dir, output_set
from .exr import describe, read_exr, write_exr
from .png import linear_to_srgb, to_rgb8, write_png
from .svg import svg_document, write_contour_outputs, write_svg
from .text import write_text


def write_outputs(gb: GBuffer, outdir: str | os.PathLike[str], stem: str) -> list[Path]:
    """``outdir/<stem>.exr`` (every layer) and ``outdir/<stem>.png`` (the beauty, sRGB)."""
    d = check_writable_dir(outdir, create=True)
    with output_set():  # both or neither
        return [write_exr(d / f"{stem}.exr", gb), write_png(d / f"{stem}.png", gb.beauty)]


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
    "write_svg",
    "write_text",
]
