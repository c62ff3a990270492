"""``mi-npr dataset``: line-drawing datasets from mesh collections, each mesh normalised and
rendered in a default studio from many views, with a manifest
(:func:`mi_npr.dataset.make_dataset`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..batch import CLUSTER_PARAMS
from ..dataset import DATASET_PARAMS, INDEX, make_dataset
from ..drawings import DRAWINGS
from ._common import (
    add_cluster,
    add_drawings,
    add_params,
    asked_drawings,
    cluster_options,
    drawing_values,
    fail,
    npr_warnings,
    progress,
    t,
    warn,
)

NAME = "dataset"
HELP = "line-drawing datasets from meshes (OBJ, PLY, STL, glTF/GLB): OUT/<mesh>/<view>_lines.png"
TABLES = (DATASET_PARAMS, CLUSTER_PARAMS)
#: The drawings of a dataset when none is switched on.
DEFAULT_DRAWINGS = ("lines", "strokes")


def add_arguments(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument(
        "meshes",
        nargs="+",
        metavar="MESH",
        help="mesh files (OBJ, PLY, STL, glTF, GLB), folders (searched recursively) or globs",
    )
    cmd.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output directory")
    cmd.add_argument(
        "--views",
        default="sphere:8",
        metavar="SPEC",
        help="sphere:N[:all] (default sphere:8), orbit:N or random:N[:SEED] (SEED: --seed)",
    )
    add_params(cmd, DATASET_PARAMS, NAME)
    add_drawings(cmd, list(DRAWINGS))
    add_cluster(cmd, NAME)
    cmd.add_argument(
        "--no-progress", action="store_true", help="no progress bars (shown on a terminal)"
    )


def run(args: argparse.Namespace) -> int:
    bars = progress(args)
    drawings = asked_drawings(args) or DEFAULT_DRAWINGS
    with npr_warnings():
        rows = make_dataset(
            args.meshes,
            args.output,
            views=args.views,
            seed=args.seed,
            drawings=drawings,
            width=args.width,
            height=args.height,
            spp=args.spp,
            views_per_launch=args.views_per_launch,
            beauty=args.beauty,
            non_manifold=args.non_manifold,
            params=drawing_values(args),
            **cluster_options(args),
            progress=bars,
        )
    skipped = [r for r in rows if r["status"] == "skipped"]
    failed = [r for r in rows if r["status"] == "failed"]
    for r in skipped:
        warn(f"skipped {r['error']}")
    for text in dict.fromkeys(r["warning"] for r in rows if r.get("warning")):
        warn(text)  # once per mesh
    if not bars:  # else the progress bar printed each line as its job ended
        for r in failed:
            fail(str(r.get("error")))
    views = [r for r in rows if r["view"] is not None]
    done = len(views) - len(failed)
    manifest = Path(args.output) / INDEX
    print(
        t(f"{done} of {len(views)} views done, {len(skipped)} meshes skipped; manifest {manifest}")
    )
    return 1 if failed else 0
