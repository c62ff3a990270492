"""``mi-npr raytree``: the shorthand of ``render --raytree`` that writes the ray-tree edges'
files alone: ``<stem>_raytree.exr/.png/.svg``."""

from __future__ import annotations

import argparse

from ..session import RENDER_PARAMS
from ._common import add_drawings, add_scenes
from .render import render_scenes

NAME = "raytree"
HELP = "shorthand of render --raytree: ray-tree edges, <stem>_raytree.exr/.png"
TABLES = (RENDER_PARAMS,)


def add_arguments(cmd: argparse.ArgumentParser) -> None:
    add_scenes(cmd, NAME)
    add_drawings(cmd, ["raytree"], switches=False)


def run(args: argparse.Namespace) -> int:
    return render_scenes(args, ("raytree",), "raytree")
