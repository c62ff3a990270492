"""``mi-npr info``: what a file holds. An EXR that mi-npr wrote: its layers, object table,
camera and metadata (:func:`mi_npr.io.describe`). A scene (``.xml``, or a bundled scene's
name): its defaults, integrator, sensors, objects, materials and emitters
(:func:`mi_npr.describe.describe_scene`)."""

from __future__ import annotations

import argparse
import json
from typing import Any

from ..describe import describe_scene
from ..io import describe, read_exr
from ._common import add_defines, t

NAME = "info"
HELP = "list what an EXR holds (layers, objects, camera) or a scene (objects, materials, lights)"
TABLES = ()


def add_arguments(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument(
        "file", metavar="FILE", help="an EXR mi-npr wrote, or a Mitsuba XML scene (or its name)"
    )
    add_defines(cmd)
    cmd.add_argument("--json", action="store_true", help="print JSON")


def _is_scene(path: str) -> bool:
    return path.lower().endswith(".xml")


def run(args: argparse.Namespace) -> int:
    if _is_scene(args.file):
        info = describe_scene(args.file, dict(args.defines))
        if args.json:
            print(json.dumps(info, indent=2))
        else:
            _print_scene(info)
        return 0
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


def _vec(v: list[float]) -> str:
    return "(" + ", ".join(f"{x:.4g}" for x in v) + ")"


def _print_scene(info: dict[str, Any]) -> None:
    print(f"{t(info['file'])}: a Mitsuba scene ({info['variant']})")
    if info["defaults"]:
        print("defaults (-D NAME=VALUE):")
        for name, d in info["defaults"].items():
            used = "" if d["used"] == d["file"] else f" (this load: {t(d['used'])})"
            print(f"  {t(name)} = {t(d['file'])}{used}")
    i = info["integrator"]
    beauty = f", beauty {t(i['beauty'])}" if i["beauty"] else ""
    print(f"integrator: {t(i['type'])}{beauty}")
    for k, s in enumerate(info["sensors"]):
        fov = "n/a" if s["fov"] is None else f"{s['fov']:.4g} deg"
        w, h = s["resolution"]
        print(
            f"sensor {k}: {t(s['kind'])}, {w}x{h}, fov {fov}, {s['spp']} spp, at "
            f"{_vec(s['origin'])} looking {_vec(s['direction'])}"
        )
    print(f"objects ({len(info['objects'])}; 0 is the background):")
    for k, o in info["objects"].items():
        print(
            f"  {k}: {t(o['name'])} ({t(o['type'])}, {o['primitives']} primitives, "
            f"material {t(o['material'])})"
        )
    print(f"materials ({len(info['materials'])}):")
    for k, v in info["materials"].items():
        print(f"  {k}: {t(v)}")
    print(f"emitters ({len(info['emitters'])}):")
    for e in info["emitters"]:
        print(f"  {t(e['name'])} ({t(e['type'])})")
