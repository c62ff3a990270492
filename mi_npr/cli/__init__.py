"""The ``mi-npr`` command: parses arguments and calls the library, nothing else.

One module per command (:mod:`.render`, :mod:`.contours`, :mod:`.raytree`, :mod:`.batch`,
:mod:`.dataset`, :mod:`.best_view`, :mod:`.fit_camera`, :mod:`.fit_shape`, :mod:`.path`,
:mod:`.foliage`, :mod:`.info`), each with its ``NAME``, ``HELP``, the library's parameter
tables its flags are built from (``TABLES``, :mod:`._common`), ``add_arguments`` and ``run``;
the drawing switches and their parameters come from the drawing registry
(:data:`mi_npr.drawings.DRAWINGS`).

Exit codes: 0 all succeeded, 1 something failed (each failure reported on one line), 2 usage
error, 130 interrupted (Ctrl-C), 143 terminated (SIGTERM); both remove the temporary files of
unfinished outputs. ``--traceback`` shows the Python traceback of an unexpected error (for bug
reports).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from collections.abc import Sequence
from importlib import metadata
from types import ModuleType

import mi_npr

# Only modules that do not import Dr.Jit at the top: this runs before the LLVM check.
from ..data import resolve
from ..errors import NprError, for_terminal, one_line
from ..memory import ENV, set_max_memory, share_malloc_arena

PROG = "mi-npr"
#: The commands, in the order ``--help`` lists them.
NAMES = (
    "render",
    "contours",
    "raytree",
    "batch",
    "dataset",
    "best-view",
    "fit-camera",
    "fit-shape",
    "path",
    "foliage",
    "info",
)


def commands() -> dict[str, ModuleType] | None:
    """The command modules by name; ``None`` when mi-npr cannot start (no usable LLVM).

    They are imported here, not at the top: they import Dr.Jit, which aborts the process on an
    unusable LLVM, and the command must report that problem in one line instead."""
    if mi_npr.LLVM is None:
        return None
    # imported here: they import Dr.Jit (see above)
    from . import (
        batch,
        best_view,
        contours,
        dataset,
        fit_camera,
        fit_shape,
        foliage,
        info,
        path,
        raytree,
        render,
    )

    modules = (
        render,
        contours,
        raytree,
        batch,
        dataset,
        best_view,
        fit_camera,
        fit_shape,
        path,
        foliage,
        info,
    )
    return {m.NAME: m for m in modules}


def _version() -> str:
    def v(name: str) -> str:
        try:
            return metadata.version(name)
        except metadata.PackageNotFoundError:
            return "not installed"

    return f"{PROG} {mi_npr.__version__} (mitsuba {v('mitsuba')}, drjit {v('drjit')})"


def build_parser() -> argparse.ArgumentParser:
    """The whole command line: global options and one sub-parser per command, every flag of a
    parameter built from the library's tables. When mi-npr cannot start, the commands take no
    arguments of their own (``main`` reports why before anything else)."""
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Non-photorealistic rendering for Mitsuba 3: exact G-buffers and lines.",
    )
    p.add_argument("--version", action="version", version=_version())
    p.add_argument("--variant", help="Mitsuba variant (default: $MI_NPR_VARIANT or llvm_ad_rgb)")
    p.add_argument("--traceback", action="store_true", help="show tracebacks of internal errors")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True)
    mods = commands()
    for name in NAMES:
        if mods is None:
            sub.add_parser(name)
            continue
        m = mods[name]
        cmd = sub.add_parser(name, allow_abbrev=name not in _EXACT, help=m.HELP)
        m.add_arguments(cmd)
    return p


#: Commands whose flags are never abbreviated (``--c`` is not ``--contours``): they take the
#: drawings' many parameters, whose names share prefixes.
_EXACT = ("render", "contours", "raytree", "batch", "dataset", "path")


def _remove_temps() -> None:
    """Temporary files of unfinished outputs (``finally`` blocks removed most already)."""
    if "mi_npr.io._atomic" in sys.modules:
        sys.modules["mi_npr.io._atomic"].remove_live_temps()


def _fail(message: str, code: int = 1) -> int:
    print(f"{PROG}: error: {for_terminal(message)}", file=sys.stderr)
    return code


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so that every ``finally`` runs (temporary files go)."""


def _on_sigterm(signum: int, frame: object) -> None:
    raise Terminated()


def main(argv: Sequence[str] | None = None) -> int:
    share_malloc_arena()  # a process of mi-npr's own (see there)
    parser = build_parser()
    # The commands' flags exist only once mi-npr starts: when it cannot, say why (in _run)
    # rather than call those flags unknown.
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
        if mi_npr.LLVM is None:  # no usable LLVM: import_module deferred the error to us
            mi_npr._llvm.configure()
        if mi_npr._api.STARTUP_ERROR is not None:  # the variant asked for cannot be activated
            raise mi_npr._api.STARTUP_ERROR
        if unknown:
            parser.parse_args(argv)  # a usage error naming the unknown arguments (exit 2)
        if args.variant:
            mi_npr.set_variant(args.variant)
        variant = str(mi_npr.mi.variant())
        reads_exr = args.command == "info" and not args.file.lower().endswith(".xml")
        if not variant.startswith(("llvm_", "cuda_")) and not reads_exr:
            given = (
                "--variant"
                if args.variant
                else "MI_NPR_VARIANT"
                if os.environ.get("MI_NPR_VARIANT")
                else "the active variant"
            )
            return _fail(
                f"{given} {variant}: mi-npr runs on Mitsuba's JIT variants only "
                "(llvm_*, cuda_*): use --variant llvm_ad_rgb"
            )
        # imported here, after the start-up checks: scene.py imports Dr.Jit
        from ..scene import SEARCH_PATH_ENV

        if getattr(args, "search_paths", None):  # for the worker processes too
            paths = [p for a in args.search_paths for p in a.split(os.pathsep) if p]
            for p in paths:
                if not os.path.isdir(p):
                    return _fail(f"-a {p}: not a folder", 2)
            os.environ[SEARCH_PATH_ENV] = os.pathsep.join(paths)
        if getattr(args, "max_memory", None):
            set_max_memory(args.max_memory)
            os.environ[ENV] = args.max_memory  # worker processes too
        if hasattr(args, "scenes"):  # a bundled scene by name: `mi-npr render scene1`
            args.scenes = [resolve(s) for s in args.scenes]
        if args.command in ("best-view", "path"):
            args.scene = resolve(args.scene)
        if args.command == "info":  # a bundled scene's name too
            args.file = resolve(args.file)
        return commands()[args.command].run(args)  # type: ignore[index]
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
        if isinstance(e, NprError):
            return _fail(str(e))
        if args.traceback:
            raise
        return _fail(f"internal error: {type(e).__name__}: {one_line(e)}")
