"""The ``mi-npr`` command: parses arguments and calls the library, nothing else.

Exit codes: 0 all succeeded, 1 something failed (each failure reported on one line), 2 usage
error. ``--traceback`` shows the Python traceback of an unexpected error (for bug reports).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path

PROG = "mi-npr"
#: The foliage styles (mi_npr.foliage.styles.STYLES), listed here so --help needs no import.
_STYLES = ("small_leaves", "large_leaves", "van_gogh", "childrens_book")


def _version() -> str:
    def v(name: str) -> str:
        try:
            return metadata.version(name)
        except metadata.PackageNotFoundError:
            return "not installed"

    from ._version import __version__

    return f"{PROG} {__version__} (mitsuba {v('mitsuba')}, drjit {v('drjit')})"


def _define(text: str) -> tuple[str, str]:
    from .batch import parse_define
    from .errors import ParameterError

    try:
        return parse_define(text)
    except ParameterError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _positive(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"{text!r} is not a positive integer")
    return n


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Non-photorealistic rendering for Mitsuba 3: exact G-buffers and lines.",
    )
    p.add_argument("--version", action="version", version=_version())
    p.add_argument("--variant", help="Mitsuba variant (default: $MI_NPR_VARIANT or llvm_ad_rgb)")
    p.add_argument("--traceback", action="store_true", help="show tracebacks of internal errors")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True)

    r = sub.add_parser("render", help="render scenes to multi-layer EXR + PNG")
    r.add_argument("scenes", nargs="+", metavar="SCENE.xml", help="Mitsuba XML scene(s)")
    r.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output directory")
    r.add_argument(
        "-D",
        dest="defines",
        action="append",
        default=[],
        type=_define,
        metavar="NAME=VALUE",
        help="set an XML <default> (repeatable), e.g. -D width=320 -D spp=16",
    )
    r.add_argument("--spp", type=_positive, help="samples per pixel of the beauty image")
    r.add_argument("--seed", type=int, default=0, help="sampler seed (default 0)")
    r.add_argument("--no-progress", action="store_true", help="no progress bar")

    f = sub.add_parser("foliage", help="turn a plant (PLY/OBJ) into a foliage scene in a style")
    f.add_argument(
        "input",
        metavar="INPUT.ply",
        help="plant: PLY/OBJ mesh of leaves, point set with normals, or procedural:tree|bush",
    )
    f.add_argument("--style", required=True, choices=_STYLES, help="drawing style (Fig. 4.8)")
    f.add_argument("-o", "--output", required=True, metavar="SCENE.xml", help="scene file to write")
    f.add_argument("--leaf-size", type=float, help="leaf primitive length (default: the style's)")
    f.add_argument("--abstraction", type=float, help="normal mixing in [0, 1] (default: style's)")
    f.add_argument("--hlps", type=_positive, metavar="K", help="number of HLPs (default: auto)")
    f.add_argument("--seed", type=int, default=0, help="seed of HLPs and leaves (default 0)")
    f.add_argument(
        "--leaves",
        choices=("components", "triangles"),
        default="components",
        help="a mesh's leaves: its connected components (default) or its triangles",
    )

    i = sub.add_parser("info", help="list the layers, object table and camera of an EXR")
    i.add_argument("file", metavar="FILE.exr")
    i.add_argument("--json", action="store_true", help="print JSON")
    return p


def _fail(message: str, code: int = 1) -> int:
    print(f"{PROG}: error: {message}", file=sys.stderr)
    return code


def _cmd_render(args: argparse.Namespace) -> int:
    import mi_npr

    from .batch import check_unique_stems, run_jobs

    check_unique_stems(args.scenes)
    outdir = mi_npr.io.check_writable_dir(args.output, create=True)
    options = dict(args.defines)  # -D spp=N and --spp N mean the same; --spp wins
    if args.spp is not None:
        options["spp"] = args.spp

    def job(scene: str) -> list[Path]:
        gb = mi_npr.render(scene, seed=args.seed, **options)
        return mi_npr.io.write_outputs(gb, outdir, Path(scene).stem)

    results = run_jobs(args.scenes, job, not args.no_progress, args.traceback)
    return _report(results)


def _report(results: list) -> int:
    for res in results:
        if res.ok:
            names = ", ".join(str(o) for o in res.outputs)
            print(f"{res.item}: {names} ({res.seconds:.2f} s)")
        else:
            _fail(res.error)
    failed = sum(not r.ok for r in results)
    if failed and len(results) > 1:
        _fail(f"{failed} of {len(results)} inputs failed")
    return 1 if failed else 0


def _cmd_foliage(args: argparse.Namespace) -> int:
    from .errors import ParameterError
    from .foliage.styles import load_plant, scene_files, write_foliage_scene

    source = Path(args.input).resolve()
    if any(p.resolve() == source for p in scene_files(args.output).values()):
        raise ParameterError(f"{args.input}: -o {args.output} would overwrite the input plant")
    plant = load_plant(args.input, seed=args.seed, leaves=args.leaves)
    written = write_foliage_scene(
        args.output,
        plant,
        args.style,
        leaf_size=args.leaf_size,
        abstraction=args.abstraction,
        k=args.hlps,
        seed=args.seed,
    )
    print(f"{args.input}: {', '.join(str(p) for p in written)} ({len(plant)} leaves)")
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    import mi_npr

    info = mi_npr.io.describe(mi_npr.io.read_exr(args.file))
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"{args.file}: {info['width']} x {info['height']}")
    print("layers:")
    for layer in info["layers"]:
        rng = "empty" if layer["min"] is None else f"[{layer['min']:.6g}, {layer['max']:.6g}]"
        extra = f", {layer['non_finite']} non-finite" if layer["non_finite"] else ""
        print(f"  {layer['name']:<18} {layer['type']:<8} {rng}{extra}  {layer['meaning']}")
    print("objects:")
    print("  0: background")
    for k, v in info["objects"].items():
        print(f"  {k}: {v}")
    cam = info["camera"]
    if cam:
        fov = "n/a" if cam["fov"] is None else f"{cam['fov']:.4g} deg"
        w, h = cam["resolution"]
        print(f"camera: {cam['kind']}, {w}x{h}, fov {fov}")
        for row in cam["to_world"]:
            print("  " + " ".join(f"{v:10.4f}" for v in row))
    for k, v in info["metadata"].items():
        print(f"{k}: {v}")
    return 0


COMMANDS = {"render": _cmd_render, "foliage": _cmd_foliage, "info": _cmd_info}


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        import mi_npr

        if mi_npr.LLVM is None:  # no usable LLVM: import_module deferred the error to us
            mi_npr._llvm.configure()

        if args.variant:
            mi_npr.set_variant(args.variant)
        return COMMANDS[args.command](args)
    except KeyboardInterrupt:
        return _fail("interrupted", 130)
    except ImportError as e:  # LLVMNotFoundError, a broken install
        return _fail(str(e).removeprefix("mi-npr: "))
    except Exception as e:
        from .errors import NprError, one_line

        if isinstance(e, NprError):
            return _fail(str(e))
        if args.traceback:
            raise
        return _fail(f"internal error: {type(e).__name__}: {one_line(e)}")


if __name__ == "__main__":
    sys.exit(main())
