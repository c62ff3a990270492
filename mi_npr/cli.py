"""The ``mi-npr`` command: parses arguments and calls the library, nothing else.

Exit codes: 0 all succeeded, 1 something failed (each failure reported on one line), 2 usage
error, 130 interrupted (Ctrl-C), 143 terminated (SIGTERM); both remove the temporary files of
unfinished outputs. ``--traceback`` shows the Python traceback of an unexpected error (for bug
reports).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path

from .params import cli_type

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


def _size(text: str) -> str:
    from .errors import ParameterError
    from .memory import parse_size

    try:
        parse_size(text)
    except ParameterError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a size such as 4G or 512M") from None
    return text


def _memory_argument(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument(
        "--max-memory",
        type=_size,
        metavar="SIZE",
        help="refuse renders estimated above SIZE (e.g. 4G; default: the memory available)",
    )


def _rgb(text: str) -> tuple[float, float, float]:
    """``R,G,B`` (linear, finite, >= 0) or one gray value."""
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) == 1:
        vals = vals * 3
    if len(vals) != 3 or not all(0 <= v < float("inf") for v in vals):
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a colour: give R,G,B (linear, >= 0), e.g. 0,0,0 or 1,0.9,0.8"
        )
    return (vals[0], vals[1], vals[2])


def _define_argument(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument(
        "-D",
        dest="defines",
        action="append",
        default=[],
        type=_define,
        metavar="NAME=VALUE",
        help="set an XML <default> (repeatable), e.g. -D width=320 -D spp=16",
    )


def _scene_batch_arguments(cmd: argparse.ArgumentParser, name: str) -> None:
    """The arguments of commands that render a batch of scenes into OUTDIR."""
    cmd.add_argument(
        "scenes",
        nargs="+",
        metavar="SCENE.xml",
        help="Mitsuba XML scene(s); a name that is no file is a bundled scene (scene1, ...)",
    )
    cmd.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output directory")
    _define_argument(cmd)
    cmd.add_argument(
        "--spp", type=cli_type(name, "--spp"), help="samples per pixel of the beauty image"
    )
    cmd.add_argument(
        "--seed", type=cli_type(name, "--seed"), default=0, help="sampler seed (default 0)"
    )
    cmd.add_argument("--no-progress", action="store_true", help="no progress bar")
    _memory_argument(cmd)


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
    _scene_batch_arguments(r, "render")
    r.add_argument(
        "--line-width",
        type=cli_type("render", "--line-width"),
        metavar="PX",
        help="npr_lines: width of every line in pixels (default: the scene's, else 1)",
    )
    r.add_argument(
        "--line-aa",
        type=cli_type("render", "--line-aa"),
        metavar="N",
        help="npr_lines: N x N rays per pixel, anti-aliased lines (default: the scene's, else 3)",
    )
    r.add_argument(
        "--line-color",
        type=_rgb,
        metavar="R,G,B",
        help="npr_lines: line colour (linear RGB) on the beauty and in <stem>_lines.png (black)",
    )
    r.add_argument(
        "--paper",
        type=_rgb,
        metavar="R,G,B",
        help="paper colour of <stem>_lines.png (linear RGB, default white 1,1,1)",
    )
    r.add_argument(
        "--cryptomatte",
        action="store_true",
        help="add Cryptomatte 1.2 layers (CryptoObject, CryptoMaterial) to the EXR",
    )

    c = sub.add_parser(
        "contours", help="apparent contours in red over the beauty render: PNG, SVG and EXR"
    )
    _scene_batch_arguments(c, "contours")
    # The same names as mi_npr.contours.METHODS / ID_MODES (not imported: parsing needs no LLVM).
    c.add_argument(
        "--method",
        choices=("border", "code_direction"),
        help="contour follower (default: the XML's npr_contours setting, else border)",
    )
    c.add_argument(
        "--id-mode",
        choices=("shape", "primitive", "component"),
        help="what one object is (default: the XML's npr_contours setting, else shape)",
    )
    c.add_argument(
        "--svg-image",
        choices=("embed", "link", "none"),
        default="embed",
        help="the beauty under the SVG's paths: embedded once (default), linked as "
        "<stem>_beauty.png beside it, or none",
    )
    c.add_argument("--no-beauty-in-svg", action="store_true", help="the same as --svg-image none")

    t = sub.add_parser(
        "raytree",
        help="ray-tree signatures and classified edges (real/reflection/refraction/shadow)",
    )
    _scene_batch_arguments(t, "raytree")
    t.add_argument(
        "--max-depth",
        type=cli_type("raytree", "--max-depth"),
        metavar="N",
        help="levels of the ray trees (default: the scene's npr_raytree max_depth, else 3)",
    )

    b = sub.add_parser(
        "best-view",
        help="find a scene's best viewpoint (paper eqs. 1-3) and write it as a Mitsuba sensor",
    )
    b.add_argument(
        "scene", metavar="SCENE.xml", help="Mitsuba XML scene, or a bundled scene's name"
    )
    b.add_argument(
        "--measure",
        required=True,
        choices=["pb", "curvature", "entropy"],
        help="viewpoint quality: pb (eq. 1), curvature (eq. 2) or entropy (eq. 3)",
    )
    b.add_argument(
        "--depth",
        type=cli_type("best-view", "--depth"),
        default=4,
        help="subdivisions of the best triangle (4)",
    )
    b.add_argument(
        "--res",
        type=cli_type("best-view", "--res"),
        default=128,
        help="ID buffer size, long side (128)",
    )
    b.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output directory")
    _define_argument(b)
    b.add_argument(
        "--ignore",
        action="append",
        default=[],
        metavar="OBJECT",
        help="an object whose pixels count as background, e.g. a floor (repeatable)",
    )
    b.add_argument("--json", action="store_true", help="print the result as JSON")
    _memory_argument(b)

    f = sub.add_parser("foliage", help="turn a plant (PLY/OBJ) into a foliage scene in a style")
    f.add_argument(
        "input",
        metavar="INPUT.ply",
        help="plant: PLY/OBJ mesh of leaves, point set with normals, or procedural:tree|bush",
    )
    f.add_argument("--style", required=True, choices=_STYLES, help="drawing style (Fig. 4.8)")
    f.add_argument("-o", "--output", required=True, metavar="SCENE.xml", help="scene file to write")
    f.add_argument(
        "--leaf-size",
        type=cli_type("foliage", "--leaf-size"),
        help="leaf primitive length (default: the style's)",
    )
    f.add_argument(
        "--abstraction",
        type=cli_type("foliage", "--abstraction"),
        help="normal mixing in [0, 1] (default: style's)",
    )
    f.add_argument("--hlps", type=cli_type("foliage", "--hlps"), metavar="K", help="number of HLPs")
    f.add_argument(
        "--seed",
        type=cli_type("foliage", "--seed"),
        default=0,
        help="seed of HLPs and leaves (default 0)",
    )
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


def _t(text: object) -> str:
    """Control characters escaped (names from files reach the terminal here)."""
    from .errors import for_terminal

    return for_terminal(text)


def _remove_temps() -> None:
    """Temporary files of unfinished outputs (``finally`` blocks removed most already)."""
    if "mi_npr.io._atomic" in sys.modules:
        sys.modules["mi_npr.io._atomic"].remove_live_temps()


def _fail(message: str, code: int = 1) -> int:
    print(f"{PROG}: error: {_t(message)}", file=sys.stderr)
    return code


def _scene_batch(args: argparse.Namespace) -> tuple[Path, dict]:
    """The checked output directory and the render options of a batch-of-scenes command
    (``spp``, ``defines``: passed as a mapping, so ``-D seed=3`` fills the XML's ``$seed``)."""
    import mi_npr

    from .batch import check_unique_stems

    check_unique_stems(args.scenes)
    outdir = mi_npr.io.check_writable_dir(args.output, create=True)
    defines = dict(args.defines)
    spp = defines.pop("spp", None)  # -D spp=N and --spp N mean the same; --spp wins
    if args.spp is not None:
        spp = args.spp
    return outdir, {"spp": spp, "defines": defines}


def _cmd_render(args: argparse.Namespace) -> int:
    import mi_npr

    from .batch import run_jobs
    from .drawing import render_lines

    outdir, options = _scene_batch(args)
    lines = {"line_width": args.line_width, "line_aa": args.line_aa, "line_color": args.line_color}

    def job(scene: str) -> list[Path]:
        gb = render_lines(scene, seed=args.seed, cryptomatte=args.cryptomatte, **lines, **options)
        return mi_npr.io.write_outputs(
            gb, outdir, Path(scene).stem, line_color=args.line_color, paper=args.paper
        )

    results = run_jobs(args.scenes, job, not args.no_progress, args.traceback)
    return _report(results)


def _cmd_contours(args: argparse.Namespace) -> int:
    import mi_npr

    from .batch import run_jobs

    outdir, options = _scene_batch(args)

    def job(scene: str) -> list[Path]:
        gb, contours, paths, strokes = mi_npr.contours.render_vector_contours(
            scene, seed=args.seed, method=args.method, id_mode=args.id_mode, **options
        )
        image = "none" if args.no_beauty_in_svg else args.svg_image
        return mi_npr.io.write_contour_outputs(
            gb, contours, outdir, Path(scene).stem, svg_image=image, paths=paths, strokes=strokes
        )

    results = run_jobs(args.scenes, job, not args.no_progress, args.traceback)
    return _report(results)


def _cmd_raytree(args: argparse.Namespace) -> int:
    import mi_npr

    from .batch import run_jobs

    outdir, options = _scene_batch(args)

    def job(scene: str) -> list[Path]:
        gb = mi_npr.raytree.render(scene, max_depth=args.max_depth, seed=args.seed, **options)
        stem = Path(scene).stem
        return mi_npr.io.write_raytree_outputs(gb, outdir, stem, mi_npr.contours.stroke_layers(gb))

    results = run_jobs(args.scenes, job, not args.no_progress, args.traceback)
    return _report(results)


def _report(results: list) -> int:
    for res in results:
        if res.ok:
            names = ", ".join(str(o) for o in res.outputs)
            print(_t(f"{res.item}: {names}") + f" ({res.seconds:.2f} s)")
        else:
            _fail(res.error)
    failed = sum(not r.ok for r in results)
    if failed and len(results) > 1:
        _fail(f"{failed} of {len(results)} inputs failed")
    return 1 if failed else 0


def _cmd_best_view(args: argparse.Namespace) -> int:
    from .viewpoint import plots_missing, write_best_view

    if why := plots_missing():
        print(f"{PROG}: note: {why}: the quality sphere picture is skipped", file=sys.stderr)
    best, outputs = write_best_view(
        args.scene,
        args.output,
        args.measure,
        args.depth,
        args.res,
        ignore=args.ignore,
        defines=dict(args.defines),
    )
    if args.json:
        info = {"scene": args.scene, **best.to_dict()}
        info["outputs"] = {k: str(v) for k, v in outputs.items()}
        print(json.dumps(info, indent=2))
        return 0
    o = ", ".join(f"{v:.4g}" for v in best.origin)
    print(f"{_t(args.scene)}: best view ({args.measure}) at ({o}), quality {best.quality:.6g}")
    print(f"  {best.evaluations} viewpoints rated at {best.size[0]}x{best.size[1]}")
    for path in outputs.values():
        print(f"  wrote {_t(path)}")
    return 0


def _cmd_foliage(args: argparse.Namespace) -> int:
    from .foliage.styles import make_scene

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
    print(_t(f"{args.input}: {', '.join(str(p) for p in written)}") + f" ({len(plant)} leaves)")
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    import mi_npr

    info = mi_npr.io.describe(mi_npr.io.read_exr(args.file))
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"{_t(args.file)}: {info['width']} x {info['height']}")
    print("layers:")
    for layer in info["layers"]:
        rng = "empty" if layer["min"] is None else f"[{layer['min']:.6g}, {layer['max']:.6g}]"
        extra = f", {layer['non_finite']} non-finite" if layer["non_finite"] else ""
        name, meaning = _t(layer["name"]), _t(layer["meaning"])
        print(f"  {name:<18} {layer['type']:<8} {rng}{extra}  {meaning}")
    print("objects:")
    print("  0: background")
    for k, v in info["objects"].items():
        print(f"  {k}: {_t(v)}")
    cam = info["camera"]
    if cam:
        fov = "n/a" if cam["fov"] is None else f"{cam['fov']:.4g} deg"
        w, h = cam["resolution"]
        print(f"camera: {_t(cam['kind'])}, {w}x{h}, fov {fov}")
        for row in cam["to_world"]:
            print("  " + " ".join(f"{v:10.4f}" for v in row))
    for k, v in info["metadata"].items():
        print(f"{_t(k)}: {_t(v)}")
    return 0


COMMANDS = {
    "render": _cmd_render,
    "contours": _cmd_contours,
    "raytree": _cmd_raytree,
    "best-view": _cmd_best_view,
    "foliage": _cmd_foliage,
    "info": _cmd_info,
}


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so that every ``finally`` runs (temporary files go)."""


def _on_sigterm(signum: int, frame: object) -> None:
    raise Terminated()


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        return _run(args)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _run(args: argparse.Namespace) -> int:
    try:
        import mi_npr

        if mi_npr.LLVM is None:  # no usable LLVM: import_module deferred the error to us
            mi_npr._llvm.configure()
        if mi_npr._api.STARTUP_ERROR is not None:  # the variant asked for cannot be activated
            raise mi_npr._api.STARTUP_ERROR
        if args.variant:
            mi_npr.set_variant(args.variant)
        if getattr(args, "max_memory", None):
            from .memory import ENV, set_max_memory

            set_max_memory(args.max_memory)
            os.environ[ENV] = args.max_memory  # worker processes too
        from mi_npr.data import resolve

        if hasattr(args, "scenes"):  # a bundled scene by name: `mi-npr render scene1`
            args.scenes = [resolve(s) for s in args.scenes]
        if args.command == "best-view":
            args.scene = resolve(args.scene)
        return COMMANDS[args.command](args)
    except KeyboardInterrupt:
        _remove_temps()
        return _fail("interrupted", 130)
    except Terminated:
        _remove_temps()
        return _fail("terminated", 128 + signal.SIGTERM)
    except BrokenPipeError:  # `mi-npr info x.exr | head`: the reader left, nothing to report
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
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
