"""``mi-npr foliage``: a plant (PLY/OBJ mesh of leaves, point set, or a procedural tree) turned
into a foliage scene in one of the thesis's styles (:func:`mi_npr.foliage.styles.make_scene`)."""

from __future__ import annotations

import argparse

from ..foliage.plant import LEAF_MODES
from ..foliage.styles import FOLIAGE_PARAMS, STYLES, make_scene
from ._common import add_params, t

NAME = "foliage"
HELP = "turn a plant (PLY/OBJ) into a foliage scene in a style"
TABLES = (FOLIAGE_PARAMS,)


def add_arguments(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument(
        "input",
        metavar="INPUT.ply",
        help="plant: PLY/OBJ mesh of leaves, point set with normals, or procedural:tree|bush",
    )
    cmd.add_argument(
        "--style", required=True, choices=list(STYLES), help="drawing style (Fig. 4.8)"
    )
    cmd.add_argument(
        "-o", "--output", required=True, metavar="SCENE.xml", help="scene file to write"
    )
    add_params(cmd, FOLIAGE_PARAMS, NAME)
    cmd.add_argument(
        "--leaves",
        choices=LEAF_MODES,
        default="components",
        help="a mesh's leaves: its connected components (default) or its triangles",
    )


def run(args: argparse.Namespace) -> int:
    plant, written = make_scene(
        args.input,
        args.output,
        args.style,
        leaf_size=args.leaf_size,
        abstraction=args.abstraction,
        k=args.hlps,
        seed=args.seed,
        leaves=args.leaves,
    )
    print(t(f"{args.input}: {', '.join(str(p) for p in written)}") + f" ({len(plant)} leaves)")
    return 0
