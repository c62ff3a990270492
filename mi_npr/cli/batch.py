"""``mi-npr batch``: scenes x viewpoints on Dask (a local cluster or a running one),
resumable, one manifest row per job (:func:`mi_npr.batch.run`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..batch import CLUSTER_PARAMS
from ..batch import run as run_batch
from ..drawings import DRAWINGS
from ..io.manifest import MANIFEST
from ..session import RENDER_PARAMS
from ._common import (
    add_cluster,
    add_drawings,
    add_paper,
    add_scenes,
    asked_drawings,
    cluster_options,
    drawing_values,
    fail,
    npr_warnings,
    progress,
    spp_and_defines,
    t,
    warn,
)

NAME = "batch"
HELP = "scenes x viewpoints on Dask (local or a cluster), resumable: OUT/<stem>/<view>.exr"
TABLES = (RENDER_PARAMS, CLUSTER_PARAMS)


def add_arguments(cmd: argparse.ArgumentParser) -> None:
    add_scenes(cmd, NAME)
    cmd.add_argument(
        "--views",
        default="scene",
        metavar="SPEC",
        help="scene (default), orbit:N[:camera], sphere:N[:all], random:N[:SEED], "
        "best:K[:MEASURE] or a JSON file of cameras (origin, target, up, fov)",
    )
    cmd.add_argument(
        "--frame",
        action="append",
        default=[],
        metavar="OBJECT",
        help="orbit, sphere, random, best views: an object they frame, instead of the objects "
        "that matter (repeatable)",
    )
    add_drawings(cmd, list(DRAWINGS))
    add_paper(cmd, "<view>")
    add_cluster(cmd, NAME)


def run(args: argparse.Namespace) -> int:
    bars = progress(args)
    params = drawing_values(args)
    spp, defines = spp_and_defines(args)
    with npr_warnings():
        rows = run_batch(
            args.scenes,
            args.views,
            out=args.output,
            drawings=asked_drawings(args),
            params=params,
            width=args.width,
            height=args.height,
            spp=None if spp is None else int(spp),
            seed=args.seed,
            defines=defines,
            **cluster_options(args),
            progress=bars,
            line_color=params.get("line_color"),
            paper=args.paper,
            frame=args.frame,
        )
    failed = [r for r in rows if r.get("status") != "done"]
    if not bars:  # else the progress bar printed each line as its job ended
        for r in failed:
            fail(str(r.get("error")))
        for r in rows:
            if r.get("warning"):
                warn(r["warning"])
    manifest = Path(args.output) / MANIFEST
    print(t(f"{len(rows) - len(failed)} of {len(rows)} jobs done; manifest {manifest}"))
    return 1 if failed else 0
