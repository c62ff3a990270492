"""``mi-npr fit-shape``: an object's translation, rotation and scale that make the scene's lines
match a line drawing, the camera held; written as JSON with a picture of the lines
(:func:`mi_npr.ad.fit.write_fit_shape`)."""

from __future__ import annotations

import argparse

from ..ad.fit import SHAPE_FIT_PARAMS, write_fit_shape
from ._common import add_defines, add_params, add_scene, add_target_drawing, t

NAME = "fit-shape"
HELP = "find the pose of one object from which a scene looks like a line drawing"
TABLES = (SHAPE_FIT_PARAMS,)


def add_arguments(cmd: argparse.ArgumentParser) -> None:
    add_scene(cmd)
    add_target_drawing(cmd)
    cmd.add_argument("--object", required=True, help="the object to move (its id in the scene)")
    add_params(cmd, SHAPE_FIT_PARAMS, NAME)
    cmd.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output directory")
    add_defines(cmd)


def run(args: argparse.Namespace) -> int:
    fit, outputs = write_fit_shape(
        args.scene,
        args.drawing,
        args.object,
        args.output,
        defines=dict(args.defines),
        iterations=args.iterations,
        lr=args.lr,
        params=args.fit,
        samples=args.samples,
    )
    tr = ", ".join(f"{v:.4g}" for v in fit.translation)
    rot = ", ".join(f"{v:.4g}" for v in fit.rotation)
    print(
        f"{t(args.scene)}: {t(args.object)} moved by ({tr}), turned by ({rot}) degrees about "
        f"x, y, z, scaled by {fit.scale:.4g}; loss {fit.loss[0]:.3g} -> {fit.loss[-1]:.3g}"
    )
    print(f"  {len(fit.loss)} steps in {fit.seconds:.1f} s")
    for path in outputs.values():
        print(f"  wrote {t(path)}")
    return 0
