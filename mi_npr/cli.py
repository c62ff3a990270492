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
import warnings
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
    _size_arguments(cmd, name)
    cmd.add_argument(
        "--seed", type=cli_type(name, "--seed"), default=0, help="sampler seed (default 0)"
    )
    cmd.add_argument(
        "--no-progress", action="store_true", help="no progress bars (shown on a terminal)"
    )
    _memory_argument(cmd)


def _size_arguments(cmd: argparse.ArgumentParser, name: str) -> None:
    """``--width``, ``--height``, ``--spp``: the film and sampler of any scene, whatever the
    names of its ``<default>``\\ s (``res``, ``resx``, ``width``...)."""
    cmd.add_argument(
        "--width",
        type=cli_type(name, "--width"),
        metavar="W",
        help="film width (alone: keeps the aspect)",
    )
    cmd.add_argument(
        "--height",
        type=cli_type(name, "--height"),
        metavar="H",
        help="film height (alone: keeps the aspect)",
    )
    cmd.add_argument(
        "--spp", type=cli_type(name, "--spp"), metavar="N", help="samples per pixel of the beauty"
    )


def _layer_params() -> dict[str, tuple]:
    """The drawings' plugin parameters (``mi_npr.pipeline.LAYERS``), read from the plugins;
    empty when mi-npr cannot start (``main`` then reports why)."""
    try:
        import mi_npr

        if mi_npr.LLVM is None or mi_npr._api.STARTUP_ERROR is not None:
            return {}
        from .drawings import DRAWINGS

        return {name: d.params for name, d in DRAWINGS.items()}
    except Exception:
        return {}


def _param_type(param: object, plugin: str) -> object:
    """Parse and check a flag's value like the plugin checks the XML's (a usage error)."""
    from .errors import ParameterError
    from .params import coerce

    def parse(text: str) -> object:
        t = getattr(param, "type", str)
        try:
            value: object = text
            if t is tuple:
                value = _rgb(text)
            elif t in (float, int):
                try:
                    value = float(text) if t is float else int(text)
                except ValueError:
                    kind = "a number" if t is float else "an integer"
                    raise argparse.ArgumentTypeError(f"{text!r} is not {kind}") from None
            return coerce(plugin, param, value)  # type: ignore[arg-type]
        except ParameterError as e:
            raise argparse.ArgumentTypeError(str(e)) from None

    return parse


#: Parameters given as repeatable flags (shell globs), joined with commas like the XML's.
_REPEATABLE = ("only", "ignore")


def _cluster_arguments(cmd: argparse.ArgumentParser, name: str) -> None:
    """``--workers``, ``--threads-per-worker``, ``--scheduler``, ``--resume``, ``--retries``:
    where the jobs of ``mi-npr batch`` (and the frames of ``mi-npr path``) run."""
    cmd.add_argument(
        "--workers",
        type=cli_type(name, "--workers"),
        metavar="N",
        help="worker processes of the local cluster (default: one per core; 0: this process)",
    )
    cmd.add_argument(
        "--threads-per-worker",
        type=cli_type(name, "--threads-per-worker"),
        metavar="K",
        help="Dr.Jit threads of each worker (default: the cores shared out)",
    )
    cmd.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="a running Dask scheduler, e.g. tcp://10.0.0.1:8786 (OUT must be shared storage)",
    )
    cmd.add_argument(
        "--resume",
        action="store_true",
        help="skip the jobs OUT/manifest.jsonl shows done with the same scene and flags",
    )
    cmd.add_argument(
        "--retries",
        type=cli_type(name, "--retries"),
        default=0,
        metavar="R",
        help="retries of a failed job (default 0)",
    )


def _layer_arguments(cmd: argparse.ArgumentParser, layers: Sequence[str]) -> None:
    """One flag per plugin parameter of ``layers`` (``--crease-angle`` for ``crease_angle``),
    generated from the plugins' PARAMS tables: a name several plugins share is one flag that
    sets it in every drawing that takes it (``--line-width``, ``--id-mode``, ``--only``)."""
    table = _layer_params()
    by_name: dict[str, list] = {}
    for layer in layers:
        for param in table.get(layer, ()):
            by_name.setdefault(param.name, []).append((layer, param))
    group = cmd.add_argument_group("drawing parameters (named after the plugins' parameters)")
    for name, entries in by_name.items():
        param = entries[0][1]
        plugins = "/".join(f"npr_{layer}" for layer, _ in entries)
        default = param.default if param.type is not tuple else ",".join(map(str, param.default))
        help_text = f"{plugins}: {param.doc} (default: the scene's, else {default!s})"
        flag = "--" + name.replace("_", "-")
        if name in _REPEATABLE:
            group.add_argument(
                flag, dest=f"p_{name}", action="append", metavar="GLOB", help=help_text
            )
        else:
            metavar = {tuple: "R,G,B", float: "X", int: "N", bool: "BOOL"}.get(param.type, "STR")
            group.add_argument(
                flag,
                dest=f"p_{name}",
                type=_param_type(param, f"npr_{entries[0][0]}"),
                metavar=metavar,
                help=help_text,
            )


def _layer_values(args: argparse.Namespace) -> dict:
    """The drawing parameters given on the command line: ``{name: value}``."""
    out = {}
    for key, value in vars(args).items():
        if key.startswith("p_") and value is not None:
            name = key[2:]
            out[name] = ",".join(value) if name in _REPEATABLE else value
    return out


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Non-photorealistic rendering for Mitsuba 3: exact G-buffers and lines.",
    )
    p.add_argument("--version", action="version", version=_version())
    p.add_argument("--variant", help="Mitsuba variant (default: $MI_NPR_VARIANT or llvm_ad_rgb)")
    p.add_argument("--traceback", action="store_true", help="show tracebacks of internal errors")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True)

    r = sub.add_parser(
        "render",
        allow_abbrev=False,
        help="render scenes: one EXR with every layer, a PNG per drawing (--lines, --contours...)",
    )
    _scene_batch_arguments(r, "render")
    r.add_argument("--lines", action="store_true", help="add the npr_lines drawing")
    r.add_argument("--contours", action="store_true", help="add the npr_contours drawing")
    r.add_argument("--raytree", action="store_true", help="add the npr_raytree drawing")
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
    r.add_argument(
        "--svg-image",
        choices=("embed", "link", "none"),
        default="embed",
        help="the beauty in <stem>_contours.svg: embedded once (default), linked, or none",
    )
    r.add_argument(
        "--no-beauty-in-svg", action="store_true", help="do not embed the beauty in the SVG"
    )
    _layer_arguments(r, ("lines", "contours", "raytree"))

    c = sub.add_parser(
        "contours",
        allow_abbrev=False,
        help="shorthand of render --contours: <stem>_contours.exr/.png/.svg",
    )
    _scene_batch_arguments(c, "contours")
    c.add_argument(
        "--svg-image",
        choices=("embed", "link", "none"),
        default="embed",
        help="the beauty under the SVG's paths: embedded once (default), linked as "
        "<stem>_beauty.png beside it, or none",
    )
    c.add_argument("--no-beauty-in-svg", action="store_true", help="the same as --svg-image none")
    _layer_arguments(c, ("contours",))

    t = sub.add_parser(
        "raytree",
        allow_abbrev=False,
        help="shorthand of render --raytree: ray-tree edges, <stem>_raytree.exr/.png",
    )
    _scene_batch_arguments(t, "raytree")
    _layer_arguments(t, ("raytree",))

    bt = sub.add_parser(
        "batch",
        allow_abbrev=False,
        help="scenes x viewpoints on Dask (local or a cluster), resumable: OUT/<stem>/<view>.exr",
    )
    _scene_batch_arguments(bt, "batch")
    bt.add_argument(
        "--views",
        default="scene",
        metavar="SPEC",
        help="scene (default), orbit:N, sphere:N[:all], best:K[:MEASURE] or a JSON file of "
        "cameras (origin, target, up, fov)",
    )
    bt.add_argument("--lines", action="store_true", help="add the npr_lines drawing")
    bt.add_argument("--contours", action="store_true", help="add the npr_contours drawing")
    bt.add_argument("--raytree", action="store_true", help="add the npr_raytree drawing")
    bt.add_argument(
        "--paper",
        type=_rgb,
        metavar="R,G,B",
        help="paper colour of <view>_lines.png (linear RGB, default white 1,1,1)",
    )
    _cluster_arguments(bt, "batch")
    _layer_arguments(bt, ("lines", "contours", "raytree"))

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
        default=3,
        help="levels of subdivision of the viewing sphere's triangles (3)",
    )
    b.add_argument(
        "--res",
        type=cli_type("best-view", "--res"),
        default=128,
        help="ID buffer size, long side (128)",
    )
    _size_arguments(b, "best-view")
    b.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output directory")
    _define_argument(b)
    b.add_argument(
        "--ignore",
        action="append",
        default=[],
        metavar="OBJECT",
        help="an object whose pixels count as background, e.g. a floor (repeatable)",
    )
    b.add_argument(
        "--allow-below",
        action="store_true",
        help="also rate viewpoints below the scene's ground (the side opposite its camera's up)",
    )
    b.add_argument(
        "--no-sphere", action="store_true", help="do not draw the quality-sphere picture"
    )
    b.add_argument("--json", action="store_true", help="print the result as JSON")
    _memory_argument(b)

    a = sub.add_parser(
        "path",
        allow_abbrev=False,
        help="render a camera path (orbit, exploration through good views, or keyframes): "
        "frames, path.json, coherence.json and videos",
    )
    a.add_argument(
        "scene", metavar="SCENE.xml", help="Mitsuba XML scene, or a bundled scene's name"
    )
    a.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output directory")
    a.add_argument(
        "--frames", type=cli_type("path", "--frames"), required=True, metavar="N", help="frames"
    )
    how = a.add_mutually_exclusive_group()
    how.add_argument(
        "--explore",
        choices=["pb", "curvature", "entropy"],
        metavar="MEASURE",
        help="explore through good views of this measure (pb, curvature, entropy; paper eqs. 1-3)",
    )
    how.add_argument(
        "--orbit", action="store_true", help="turn about the scene's up axis (the default)"
    )
    how.add_argument(
        "--keys", metavar="CAMERAS.json", help="a smooth path through these keyframe cameras"
    )
    a.add_argument(
        "--explore-ignore",
        action="append",
        default=[],
        metavar="OBJECT",
        help="--explore: an object counted as background by the measure (a floor); repeatable",
    )
    a.add_argument(
        "--degrees",
        type=cli_type("path", "--degrees"),
        default=360.0,
        metavar="X",
        help="orbit angle (default 360)",
    )
    a.add_argument(
        "--max-speed",
        type=cli_type("path", "--max-speed"),
        default=4.0,
        metavar="DEG",
        help="--explore: most degrees the camera moves per frame (default 4)",
    )
    a.add_argument(
        "--max-turn",
        type=cli_type("path", "--max-turn"),
        default=12.0,
        metavar="DEG",
        help="--explore: most degrees its direction of motion turns per frame (default 12)",
    )
    a.add_argument("--lines", action="store_true", help="add the npr_lines drawing")
    a.add_argument("--contours", action="store_true", help="add the npr_contours drawing")
    a.add_argument("--raytree", action="store_true", help="add the npr_raytree drawing")
    a.add_argument(
        "--video", choices=["mp4", "gif"], metavar="FORMAT", help="also write videos: mp4 or gif"
    )
    a.add_argument(
        "--fps", type=cli_type("path", "--fps"), default=24, metavar="N", help="video rate"
    )
    a.add_argument(
        "--variants",
        action="store_true",
        help="also measure the popping of the four line variants (gray, black/white, with and "
        "without the pre-filter and eq. 5.2) into coherence.json",
    )
    _define_argument(a)
    _size_arguments(a, "path")
    a.add_argument(
        "--seed", type=cli_type("path", "--seed"), default=0, help="sampler seed (default 0)"
    )
    a.add_argument("--no-progress", action="store_true", help="no progress bar")
    _memory_argument(a)
    _cluster_arguments(a, "path")
    _layer_arguments(a, ("lines", "contours", "raytree"))

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
    (``spp``, ``resolution``, ``defines``: passed as a mapping, so ``-D seed=3`` fills the
    XML's ``$seed``)."""
    import mi_npr

    from .batch import check_unique_stems

    check_unique_stems(args.scenes)
    outdir = mi_npr.io.check_writable_dir(args.output, create=True)
    defines = dict(args.defines)
    spp = defines.pop("spp", None)  # -D spp=N and --spp N mean the same; --spp wins
    if args.spp is not None:
        spp = args.spp
    return outdir, {"spp": spp, "defines": defines, "resolution": _resolution(args)}


def _resolution(args: argparse.Namespace) -> tuple[int | None, int | None] | None:
    """``--width``/``--height`` as a film size (``None``: the scene's)."""
    if args.width is None and args.height is None:
        return None
    return (args.width, args.height)


def _run_drawings(args: argparse.Namespace, drawings: tuple[str, ...], only: str | None) -> int:
    """``render`` (``only=None``) and its shorthands ``contours``/``raytree``."""
    import mi_npr

    from .batch import run_jobs
    from .pipeline import render_layers

    outdir, options = _scene_batch(args)
    params = _layer_values(args)
    progress = not args.no_progress

    def job(scene: str) -> list[Path]:
        result = render_layers(
            scene,
            drawings,
            params,
            scene_drawings=only is None,
            seed=args.seed,
            progress=progress,
            cryptomatte=getattr(args, "cryptomatte", False),
            **options,
        )
        no_image = getattr(args, "no_beauty_in_svg", False)
        return mi_npr.io.write_layered_outputs(
            result,
            outdir,
            Path(scene).stem,
            only=only,
            line_color=params.get("line_color"),
            paper=getattr(args, "paper", None),
            svg_image="none" if no_image else getattr(args, "svg_image", "embed"),
        )

    results = run_jobs(args.scenes, job, progress, args.traceback, on_result=_result_line)
    return _exit_code(results)


def _cmd_render(args: argparse.Namespace) -> int:
    asked = tuple(d for d in ("lines", "contours", "raytree") if getattr(args, d))
    return _run_drawings(args, asked, None)


def _cmd_contours(args: argparse.Namespace) -> int:
    return _run_drawings(args, ("contours",), "contours")


def _cmd_raytree(args: argparse.Namespace) -> int:
    return _run_drawings(args, ("raytree",), "raytree")


def _result_line(res: object) -> tuple[str, bool]:
    """The line printed as soon as one scene is done, and whether it is an error."""
    if res.ok:  # type: ignore[attr-defined]
        names = ", ".join(str(o) for o in res.outputs)  # type: ignore[attr-defined]
        line = f"{res.item}: {names} ({res.seconds:.2f} s)"  # type: ignore[attr-defined]
        return _t(line), False
    return _t(f"{PROG}: error: {res.error}"), True  # type: ignore[attr-defined]


def _exit_code(results: list) -> int:
    failed = sum(not r.ok for r in results)
    if failed and len(results) > 1:
        _fail(f"{failed} of {len(results)} inputs failed")
    return 1 if failed else 0


def _cmd_batch(args: argparse.Namespace) -> int:
    from .batch import run
    from .io.manifest import MANIFEST

    asked = [d for d in ("lines", "contours", "raytree") if getattr(args, d)]
    params = _layer_values(args)
    defines = dict(args.defines)
    spp = defines.pop("spp", None)
    if args.spp is not None:
        spp = args.spp
    rows = run(
        args.scenes,
        args.views,
        out=args.output,
        drawings=asked,
        params=params,
        width=args.width,
        height=args.height,
        spp=None if spp is None else int(spp),
        seed=args.seed,
        defines=defines,
        workers=args.workers,
        threads_per_worker=args.threads_per_worker,
        scheduler=args.scheduler,
        resume=args.resume,
        retries=args.retries,
        progress=not args.no_progress,
        line_color=params.get("line_color"),
        paper=args.paper,
    )
    failed = [r for r in rows if r.get("status") != "done"]
    if args.no_progress:  # else the progress bar printed each line as its job ended
        for r in failed:
            _fail(str(r.get("error")))
        for r in rows:
            if r.get("warning"):
                print(f"{PROG}: warning: {_t(r['warning'])}", file=sys.stderr)
    manifest = Path(args.output) / MANIFEST
    print(_t(f"{len(rows) - len(failed)} of {len(rows)} jobs done; manifest {manifest}"))
    return 1 if failed else 0


def _cmd_best_view(args: argparse.Namespace) -> int:
    from .viewpoint import plots_missing, write_best_view

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
            resolution=_resolution(args),
            spp=args.spp,
        )
    for w in caught:
        if issubclass(w.category, UserWarning):
            print(f"{PROG}: warning: {_t(w.message)}", file=sys.stderr)
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


def _cluster(args: argparse.Namespace) -> dict | None:
    """``mi-npr path``'s frames as batch jobs when a cluster option is given, else ``None``."""
    given = {
        "workers": args.workers,
        "threads_per_worker": args.threads_per_worker,
        "scheduler": args.scheduler,
    }
    given = {k: v for k, v in given.items() if v is not None}
    if not given and not args.resume and not args.retries:
        return None
    return {**given, "resume": args.resume, "retries": args.retries}


def _cmd_path(args: argparse.Namespace) -> int:
    import mi_npr

    from .paths import render_path

    outdir = mi_npr.io.check_writable_dir(args.output, create=True)
    defines = dict(args.defines)
    spp = defines.pop("spp", None)
    result = render_path(
        args.scene,
        outdir,
        args.frames,
        tuple(d for d in ("lines", "contours", "raytree") if getattr(args, d)),
        _layer_values(args),
        explore_measure=args.explore,
        explore_ignore=args.explore_ignore,
        keys=args.keys,
        degrees=args.degrees,
        max_speed=args.max_speed,
        max_turn=args.max_turn,
        resolution=_resolution(args),
        spp=args.spp if args.spp is not None else spp,
        defines=defines,
        seed=args.seed,
        video=args.video,
        fps=args.fps,
        variants=args.variants,
        progress=not args.no_progress and sys.stderr.isatty(),
        cluster=_cluster(args),
    )
    c = result.coherence
    print(f"{_t(args.scene)}: {args.frames} frames in {_t(outdir)}")
    if c is not None and c.get("overall") is not None:
        print(f"  popping ({c['layer']}): {c['overall']:.4f} of the line ink per frame pair")
    for name, v in (c or {}).get("variants", {}).items():
        print(f"  popping ({name}): {v['overall']:.4f}")
    for path in result.videos or []:
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
    "batch": _cmd_batch,
    "best-view": _cmd_best_view,
    "path": _cmd_path,
    "foliage": _cmd_foliage,
    "info": _cmd_info,
}


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so that every ``finally`` runs (temporary files go)."""


def _on_sigterm(signum: int, frame: object) -> None:
    raise Terminated()


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    # The drawing flags come from the plugins, which exist only once mi-npr starts: when it
    # cannot, say why (in _run) rather than call those flags unknown.
    args, unknown = parser.parse_known_args(argv)
    previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        return _run(parser, args, unknown, argv)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _run(
    parser: argparse.ArgumentParser,
    args: argparse.Namespace,
    unknown: list[str],
    argv: Sequence[str] | None,
) -> int:
    try:
        import mi_npr

        if mi_npr.LLVM is None:  # no usable LLVM: import_module deferred the error to us
            mi_npr._llvm.configure()
        if mi_npr._api.STARTUP_ERROR is not None:  # the variant asked for cannot be activated
            raise mi_npr._api.STARTUP_ERROR
        if unknown:
            parser.parse_args(argv)  # a usage error naming the unknown arguments (exit 2)
        if args.variant:
            mi_npr.set_variant(args.variant)
        if getattr(args, "max_memory", None):
            from .memory import ENV, set_max_memory

            set_max_memory(args.max_memory)
            os.environ[ENV] = args.max_memory  # worker processes too
        from mi_npr.data import resolve

        if hasattr(args, "scenes"):  # a bundled scene by name: `mi-npr render scene1`
            args.scenes = [resolve(s) for s in args.scenes]
        if args.command in ("best-view", "path"):
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
