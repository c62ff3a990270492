"""``mi-npr contours``: the shorthand of ``render --contours`` that writes the contours'
files alone: ``<stem>_contours.exr/.png/.svg``."""

from __future__ import annotations

import argparse

from ..session import RENDER_PARAMS
from ._common import add_drawings, add_scenes
from .render import add_svg_image, render_scenes

NAME = "contours"
HELP = "shorthand of render --contours: <stem>_contours.exr/.png/.svg"
TABLES = (RENDER_PARAMS,)


def add_arguments(cmd: argparse.ArgumentParser) -> None:
    add_scenes(cmd, NAME)
    add_svg_image(
        cmd,
        "the beauty under the SVG's paths: embedded once (default), linked as "
        "<stem>_beauty.png beside it, or none",
    )
    cmd.add_argument("--no-beauty-in-svg", action="store_true", help="the same as --svg-image none")
    add_drawings(cmd, ["contours"], switches=False)


def run(args: argparse.Namespace) -> int:
    return render_scenes(args, ("contours",), "contours")
