"""``mi-npr fit-camera``: the camera from a sketch: the camera whose lines match a line drawing
of the scene, written as a Mitsuba ``<sensor>`` with a picture of its lines
(:func:`mi_npr.ad.write_fit_camera`)."""

from __future__ import annotations

import argparse
import json

from ..ad.fit import FIT_PARAMS, camera_error, write_fit_camera
from ._common import add_defines, add_params, add_scene, add_target_drawing, t

NAME = "fit-camera"
HELP = "find the camera from which a scene looks like a line drawing; write it as a sensor"
TABLES = (FIT_PARAMS,)


def add_arguments(cmd: argparse.ArgumentParser) -> None:
    add_scene(cmd)
    add_target_drawing(cmd)
    add_params(cmd, FIT_PARAMS, NAME)
    cmd.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output directory")
    add_defines(cmd)
    cmd.add_argument("--json", action="store_true", help="print the result as JSON")


def run(args: argparse.Namespace) -> int:
    fit, outputs = write_fit_camera(
        args.scene,
        args.drawing,
        args.output,
        defines=dict(args.defines),
        iterations=args.iterations,
        lr=args.lr,
        params=args.fit,
        samples=args.samples,
    )
    degrees, distance = camera_error(fit.camera, fit.start)
    if args.json:
        info = {"scene": args.scene, "drawing": args.drawing, **fit.camera.to_dict()}
        info.update(
            loss=fit.loss[-1],
            iterations=len(fit.loss),
            seconds=fit.seconds,
            moved_degrees=degrees,
            moved_distance=distance,
            outputs={k: str(v) for k, v in outputs.items()},
        )
        print(json.dumps(info, indent=2))
        return 0
    o = ", ".join(f"{v:.4g}" for v in fit.camera.origin)
    print(
        f"{t(args.scene)}: camera at ({o}), moved {degrees:.3g} degrees and "
        f"{100 * distance:.3g}% from the start, loss {fit.loss[0]:.3g} -> {fit.loss[-1]:.3g}"
    )
    print(f"  {len(fit.loss)} steps in {fit.seconds:.1f} s")
    for path in outputs.values():
        print(f"  wrote {t(path)}")
    return 0
