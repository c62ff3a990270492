"""``mi-npr path``: a camera path (an orbit, an exploration through good views, or a smooth
path through keyframes) rendered frame by frame, with ``path.json``, ``coherence.json`` and
videos (:func:`mi_npr.paths.render_path`)."""

from __future__ import annotations

import argparse

from ..batch import CLUSTER_PARAMS
from ..drawings import DRAWINGS
from ..io import check_writable_dir
from ..params import entry
from ..paths import PATH_PARAMS, render_path
from ..session import RENDER_PARAMS
from ..viewpoint.measures import MEASURES
from ._common import (
    add_cluster,
    add_defines,
    add_drawings,
    add_memory,
    add_param,
    add_params,
    add_render_settings,
    add_scene,
    asked_drawings,
    cluster_options,
    drawing_values,
    npr_warnings,
    progress,
    resolution,
    spp_and_defines,
    t,
)

NAME = "path"
HELP = (
    "render a camera path (orbit, exploration through good views, or keyframes): "
    "frames, path.json, coherence.json and videos"
)
TABLES = (RENDER_PARAMS, PATH_PARAMS, CLUSTER_PARAMS)


def add_arguments(cmd: argparse.ArgumentParser) -> None:
    add_scene(cmd)
    cmd.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output directory")
    add_param(cmd, entry(PATH_PARAMS, "frames"), NAME, required=True)
    how = cmd.add_mutually_exclusive_group()
    how.add_argument(
        "--explore",
        choices=list(MEASURES),
        metavar="MEASURE",
        help="explore through good views of this measure (pb, curvature, entropy; paper eqs. 1-3)",
    )
    how.add_argument(
        "--orbit", action="store_true", help="turn about the scene's up axis (the default)"
    )
    how.add_argument(
        "--keys", metavar="CAMERAS.json", help="a smooth path through these keyframe cameras"
    )
    cmd.add_argument(
        "--orbit-target",
        choices=["objects", "camera"],
        default="objects",
        help="--orbit about the centre of the framed objects (default) or the scene camera's "
        "own target (its view line across from that centre: frame 0 is the sensor's view)",
    )
    cmd.add_argument(
        "--explore-ignore",
        action="append",
        default=[],
        metavar="OBJECT",
        help="--explore: an object counted as background by the measure (a floor); repeatable",
    )
    cmd.add_argument(
        "--frame",
        action="append",
        default=[],
        metavar="OBJECT",
        help="--orbit, --explore: an object the path frames, instead of the objects that "
        "matter (repeatable)",
    )
    add_params(
        cmd, (p for p in PATH_PARAMS if p.name in ("degrees", "max_speed", "max_turn")), NAME
    )
    add_drawings(cmd, list(DRAWINGS))
    cmd.add_argument(
        "--video", choices=["mp4", "gif"], metavar="FORMAT", help="also write videos: mp4 or gif"
    )
    add_param(cmd, entry(PATH_PARAMS, "fps"), NAME)
    cmd.add_argument(
        "--variants",
        action="store_true",
        help="also measure the popping of the four line variants (gray, black/white, with and "
        "without the pre-filter and eq. 5.2) into coherence.json",
    )
    add_defines(cmd)
    add_render_settings(cmd, NAME)
    cmd.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_memory(cmd)
    add_cluster(cmd, NAME)


def _cluster(args: argparse.Namespace) -> dict | None:
    """The frames as batch jobs when a cluster option is given, else ``None``."""
    options = cluster_options(args)
    flags = ("workers", "threads_per_worker", "scheduler", "job_timeout")
    given = {k: options[k] for k in flags if options[k] is not None}
    if not given and not args.resume and not args.retries:
        return None
    return {
        **given,
        "resume": args.resume,
        "retries": args.retries,
        "dashboard": options["dashboard"],
        "on_dashboard": options["on_dashboard"],
    }


def run(args: argparse.Namespace) -> int:
    outdir = check_writable_dir(args.output, create=True)
    spp, defines = spp_and_defines(args)
    with npr_warnings():
        result = render_path(
            args.scene,
            outdir,
            args.frames,
            asked_drawings(args),
            drawing_values(args),
            explore_measure=args.explore,
            explore_ignore=args.explore_ignore,
            frame=args.frame,
            orbit_target=args.orbit_target,
            keys=args.keys,
            degrees=args.degrees,
            max_speed=args.max_speed,
            max_turn=args.max_turn,
            resolution=resolution(args),
            spp=spp,
            defines=defines,
            seed=args.seed,
            video=args.video,
            fps=args.fps,
            variants=args.variants,
            progress=progress(args),
            cluster=_cluster(args),
        )
    c = result.coherence
    print(f"{t(args.scene)}: {args.frames} frames in {t(outdir)}")
    if c is not None and c.get("overall") is not None:
        print(f"  popping ({c['layer']}): {c['overall']:.4f} of the line ink per frame pair")
    for name, v in (c or {}).get("variants", {}).items():
        print(f"  popping ({name}): {v['overall']:.4f}")
    for path in result.videos or []:
        print(f"  wrote {t(path)}")
    return 0
