"""``mi-npr info``: the layers, object table, camera and metadata of an EXR that mi-npr wrote
(:func:`mi_npr.io.describe`)."""

from __future__ import annotations

import argparse
import json

from ..io import describe, read_exr
from ._common import t

NAME = "info"
HELP = "list the layers, object table and camera of an EXR"
TABLES = ()


def add_arguments(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument("file", metavar="FILE.exr")
    cmd.add_argument("--json", action="store_true", help="print JSON")


def run(args: argparse.Namespace) -> int:
    info = describe(read_exr(args.file))
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"{t(args.file)}: {info['width']} x {info['height']}")
    print("layers:")
    for layer in info["layers"]:
        rng = "empty" if layer["min"] is None else f"[{layer['min']:.6g}, {layer['max']:.6g}]"
        extra = f", {layer['non_finite']} non-finite" if layer["non_finite"] else ""
        name, meaning = t(layer["name"]), t(layer["meaning"])
        print(f"  {name:<18} {layer['type']:<8} {rng}{extra}  {meaning}")
    print("objects:")
    print("  0: background")
    for k, v in info["objects"].items():
        print(f"  {k}: {t(v)}")
    cam = info["camera"]
    if cam:
        fov = "n/a" if cam["fov"] is None else f"{cam['fov']:.4g} deg"
        w, h = cam["resolution"]
        print(f"camera: {t(cam['kind'])}, {w}x{h}, fov {fov}")
        for row in cam["to_world"]:
            print("  " + " ".join(f"{v:10.4f}" for v in row))
    for k, v in info["metadata"].items():
        print(f"{t(k)}: {t(v)}")
    return 0
