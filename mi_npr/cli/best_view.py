"""``mi-npr best-view``: a scene's best viewpoint by the paper's quality measures (eqs. 1-3),
written as a Mitsuba ``<sensor>`` with its render and the quality sphere
(:func:`mi_npr.viewpoint.write_best_view`)."""

from __future__ import annotations

import argparse
import json
import sys
import warnings

from ..viewpoint import plots_missing, write_best_view
from ..viewpoint.measures import MEASURES
from ..viewpoint.search import SEARCH_PARAMS
from ._common import (
    PROG,
    add_defines,
    add_memory,
    add_params,
    add_render_settings,
    add_scene,
    resolution,
    t,
    warn,
)

NAME = "best-view"
HELP = "find a scene's best viewpoint (paper eqs. 1-3) and write it as a Mitsuba sensor"
TABLES = (SEARCH_PARAMS,)


def add_arguments(cmd: argparse.ArgumentParser) -> None:
    add_scene(cmd)
    cmd.add_argument(
        "--measure",
        required=True,
        choices=list(MEASURES),
        help="viewpoint quality: pb (eq. 1), curvature (eq. 2) or entropy (eq. 3)",
    )
    add_params(cmd, SEARCH_PARAMS, NAME)
    add_render_settings(cmd, NAME, seed=False)
    cmd.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output directory")
    add_defines(cmd)
    cmd.add_argument(
        "--ignore",
        action="append",
        default=[],
        metavar="OBJECT",
        help="an object whose pixels count as background, e.g. a floor (repeatable)",
    )
    cmd.add_argument(
        "--frame",
        action="append",
        default=[],
        metavar="OBJECT",
        help="an object the views frame, instead of the objects that matter (repeatable)",
    )
    cmd.add_argument(
        "--allow-below",
        action="store_true",
        help="also rate viewpoints below the scene's ground (the side opposite its camera's up)",
    )
    cmd.add_argument(
        "--no-sphere", action="store_true", help="do not draw the quality-sphere picture"
    )
    cmd.add_argument("--json", action="store_true", help="print the result as JSON")
    add_memory(cmd)


def run(args: argparse.Namespace) -> int:
    if not args.no_sphere and (why := plots_missing()):
        print(f"{PROG}: note: {why}: the quality sphere picture is skipped", file=sys.stderr)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        best, outputs = write_best_view(
            args.scene,
            args.output,
            args.measure,
            args.depth,
            args.res,
            ignore=args.ignore,
            allow_below=args.allow_below,
            sphere=not args.no_sphere,
            defines=dict(args.defines),
            resolution=resolution(args),
            spp=args.spp,
            frame=args.frame,
        )
    for w in caught:
        if issubclass(w.category, UserWarning):
            warn(w.message)
    if args.json:
        info = {"scene": args.scene, **best.to_dict()}
        info["outputs"] = {k: str(v) for k, v in outputs.items()}
        print(json.dumps(info, indent=2))
        return 0
    o = ", ".join(f"{v:.4g}" for v in best.origin)
    print(f"{t(args.scene)}: best view ({args.measure}) at ({o}), quality {best.quality:.6g}")
    print(f"  {best.evaluations} viewpoints rated at {best.size[0]}x{best.size[1]}")
    for path in outputs.values():
        print(f"  wrote {t(path)}")
    return 0
