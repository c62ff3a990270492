"""What the commands share: flags built from the library's parameter tables, the arguments of
every command that renders, and the one-line reports.

A flag is a parameter of a table (:class:`~mi_npr.params.Param`) with ``_`` written ``-``
(``threads_per_worker`` is ``--threads-per-worker``); its value is parsed and checked by the
parameter's own rule, so a bad value is a usage error naming the flag (exit 2).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any

from ..batch import CLUSTER_PARAMS, DASHBOARD, parse_define
from ..drawings import DRAWINGS, shared_params
from ..errors import NprWarning, ParameterError, for_terminal
from ..memory import parse_size
from ..params import Param, coerce, problem
from ..session import RENDER_PARAMS

PROG = "mi-npr"

#: Drawing parameters given as repeatable flags (shell globs), joined with commas like the XML's.
REPEATABLE = ("only", "ignore")


def flag(name: str) -> str:
    """The flag of parameter ``name``: ``--threads-per-worker`` for ``threads_per_worker``."""
    return "--" + name.replace("_", "-")


def t(text: object) -> str:
    """Control characters escaped (names from files reach the terminal here)."""
    return for_terminal(text)


def fail(message: str, code: int = 1) -> int:
    """Report ``message`` as ``mi-npr: error: ...`` on stderr; returns ``code``."""
    print(f"{PROG}: error: {t(message)}", file=sys.stderr)
    return code


def warn(message: object) -> None:
    print(f"{PROG}: warning: {t(message)}", file=sys.stderr)


@contextlib.contextmanager
def npr_warnings() -> Iterator[None]:
    """Inside the block, the library's :class:`~mi_npr.errors.NprWarning`\\ s are printed as
    they happen, one ``mi-npr: warning:`` line each (others as Python prints them)."""
    with warnings.catch_warnings():
        warnings.simplefilter("always", NprWarning)
        shown = warnings.showwarning

        def show(message: Any, category: type, *rest: Any, **kw: Any) -> None:
            if issubclass(category, NprWarning):
                warn(message)
            else:
                shown(message, category, *rest, **kw)

        warnings.showwarning = show
        yield


# ---------------------------------------------------------------------------- value parsing


def rgb(text: str) -> tuple[float, float, float]:
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


def _define(text: str) -> tuple[str, str]:
    try:
        return parse_define(text)
    except ParameterError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _glob(text: str) -> str:
    """A shell glob of ``--only``/``--ignore``: an empty one would select nothing on purpose
    yet mean every object (the library's empty selection), so it is refused."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty pattern (give a glob such as 'sphere*')")
    return text


def _size(text: str) -> str:
    try:
        parse_size(text)
    except ParameterError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a size such as 4G or 512M") from None
    return text


def param_type(p: Param, who: str, plain: bool = True) -> Callable[[str], Any]:
    """An ``argparse`` ``type=`` that parses a flag's text as ``p``'s type and checks it by
    ``p``'s rule, like the library and the XML do; a bad value is a usage error. ``plain``:
    the message names only the text and the rule (a command's own flag), else the parameter
    as the plugin's XML check does (a drawing's flag)."""

    def parse(text: str) -> Any:
        value: Any = text
        if p.type is tuple:
            value = rgb(text)
        elif p.type in (int, float):
            try:
                value = int(text) if p.type is int else float(text)
            except ValueError:
                kind = "an integer" if p.type is int else "a number"
                raise argparse.ArgumentTypeError(f"{text!r} is not {kind}") from None
            why = problem(p, value) if plain else None
            if why:
                raise argparse.ArgumentTypeError(f"{text!r}: {why}")
        try:
            return coerce(who, p, value)
        except ParameterError as e:
            raise argparse.ArgumentTypeError(str(e)) from None

    parse.param = p  # type: ignore[attr-defined]  # the table entry, for the CLI reference
    return parse


_METAVARS = {tuple: "R,G,B", float: "X", int: "N", bool: "BOOL"}


def add_param(
    cmd: Any, p: Param, who: str, *, help: str | None = None, plain: bool = True, **kwargs: Any
) -> argparse.Action:
    """The flag of ``p`` on ``cmd`` (a parser or an argument group): its type, rule, default and
    help from the table (``plain``: :func:`param_type`)."""
    text = help or p.doc
    if p.default is not None and "default" not in text and "required" not in kwargs:
        shown = ",".join(map(str, p.default)) if isinstance(p.default, tuple) else p.default
        text = f"{text} (default {shown})"
    kwargs.setdefault("metavar", _METAVARS.get(p.type, "STR"))
    kwargs.setdefault("default", p.default)
    return cmd.add_argument(flag(p.name), type=param_type(p, who, plain), help=text, **kwargs)


def add_params(cmd: Any, params: Iterable[Param], who: str) -> None:
    for p in params:
        add_param(cmd, p, who)


# ------------------------------------------------------------------------ shared arguments


def add_defines(cmd: argparse.ArgumentParser) -> None:
    """``-D NAME=VALUE`` and ``-a PATH``: what every command that loads a scene takes."""
    cmd.add_argument(
        "-a",
        dest="search_paths",
        action="append",
        default=[],
        metavar="PATH",
        help="also look for the files a scene names in PATH (repeatable, or several joined by "
        f"{os.pathsep!r}), as Mitsuba's own -a",
    )
    cmd.add_argument(
        "-D",
        dest="defines",
        action="append",
        default=[],
        type=_define,
        metavar="NAME=VALUE",
        help="set an XML <default> (repeatable), e.g. -D width=320 -D spp=16",
    )


def add_memory(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument(
        "--max-memory",
        type=_size,
        metavar="SIZE",
        help="refuse renders estimated above SIZE (e.g. 4G; default: the memory available)",
    )


def add_render_settings(cmd: argparse.ArgumentParser, who: str, seed: bool = True) -> None:
    """``--width``, ``--height``, ``--spp`` (and ``--seed``): the film and the sampler of any
    scene, whatever the names of its ``<default>``\\ s (``res``, ``resx``, ``width``...)."""
    add_params(cmd, (p for p in RENDER_PARAMS if seed or p.name != "seed"), who)


def add_scenes(cmd: argparse.ArgumentParser, who: str) -> None:
    """The arguments of the commands that render a batch of scenes into OUTDIR."""
    cmd.add_argument(
        "scenes",
        nargs="+",
        metavar="SCENE.xml",
        help="Mitsuba XML scene(s); a name that is no file is a bundled scene (scene1, ...)",
    )
    cmd.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output directory")
    add_defines(cmd)
    add_render_settings(cmd, who)
    cmd.add_argument(
        "--no-progress", action="store_true", help="no progress bars (shown on a terminal)"
    )
    add_memory(cmd)


def add_target_drawing(cmd: argparse.ArgumentParser) -> None:
    """The positional ``DRAWING.png`` of the fitting commands (``fit-camera``, ``fit-shape``)."""
    cmd.add_argument(
        "drawing",
        metavar="DRAWING.png",
        help="the line drawing (dark ink on light paper, PNG, or an SVG of paths), the size of "
        "the scene's film",
    )


def add_scene(cmd: argparse.ArgumentParser) -> None:
    cmd.add_argument(
        "scene", metavar="SCENE.xml", help="Mitsuba XML scene, or a bundled scene's name"
    )


def add_cluster(cmd: argparse.ArgumentParser, who: str) -> None:
    """Where the jobs of ``mi-npr batch`` (and the frames of ``mi-npr path``) run."""
    add_params(cmd, CLUSTER_PARAMS[:2], who)
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
    add_params(cmd, CLUSTER_PARAMS[2:], who)
    cmd.add_argument(
        "--dashboard",
        default=DASHBOARD,
        metavar="HOST:PORT",
        help="where the local cluster's dashboard listens (default: this machine only, a free "
        "port; :8787 for every interface); its link is printed",
    )


def cluster_options(args: argparse.Namespace) -> dict[str, Any]:
    """The values of :func:`add_cluster`'s flags, as :func:`mi_npr.batch.run`'s keywords (the
    dashboard's link printed on stderr)."""
    names = ("workers", "threads_per_worker", "scheduler", "resume", "retries", "job_timeout")
    options = {k: getattr(args, k) for k in names}
    options["dashboard"] = args.dashboard
    options["on_dashboard"] = lambda link: print(
        f"{PROG}: dashboard {link}", file=sys.stderr, flush=True
    )
    return options


def add_paper(cmd: argparse.ArgumentParser, stem: str) -> None:
    """``--paper``: the paper colour of the lines drawing's picture."""
    cmd.add_argument(
        "--paper",
        type=rgb,
        metavar="R,G,B",
        help=f"paper colour of {stem}_lines.png (linear RGB, default white 1,1,1)",
    )


def add_drawings(
    cmd: argparse.ArgumentParser, names: Sequence[str], *, switches: bool = True
) -> None:
    """One switch per drawing of ``names`` (``--lines``) and one flag per parameter of their
    tables (``--crease-angle`` for ``crease_angle``): a name several drawings share is one flag
    that sets it in every drawing that takes it (``--line-width``, ``--id-mode``, ``--only``)."""
    if switches:
        for name in names:
            d = DRAWINGS[name]
            what = f"the {d.plugin} drawing: " if d.plugin else ""
            cmd.add_argument(flag(name), action="store_true", help=f"add {what}{d.summary}")
    group = cmd.add_argument_group("drawing parameters (named after the plugins' parameters)")
    for name, entries in shared_params(names).items():
        p = entries[0][1]
        takers = "/".join(DRAWINGS[d].plugin or d for d, _ in entries)
        shown = ",".join(map(str, p.default)) if isinstance(p.default, tuple) else p.default
        text = f"{takers}: {p.doc} (default: the scene's, else {shown!s})"
        if name in REPEATABLE:
            group.add_argument(
                flag(name), dest=f"p_{name}", action="append", metavar="GLOB", help=text, type=_glob
            )
        else:
            who = DRAWINGS[entries[0][0]].plugin or entries[0][0]
            add_param(group, p, who, dest=f"p_{name}", default=None, help=text, plain=False)


def asked_drawings(args: argparse.Namespace) -> tuple[str, ...]:
    """The drawings switched on (``--lines``, ...), in the registry's order."""
    return tuple(name for name in DRAWINGS if getattr(args, name, False))


def drawing_values(args: argparse.Namespace) -> dict[str, Any]:
    """The drawing parameters given on the command line: ``{name: value}``."""
    out = {}
    for key, value in vars(args).items():
        if key.startswith("p_") and value is not None:
            name = key[2:]
            out[name] = ",".join(value) if name in REPEATABLE else value
    return out


def progress(args: argparse.Namespace) -> bool:
    """Progress bars: on a terminal only (a log file or a pipe gets the lines alone), and not
    with ``--no-progress``."""
    return not args.no_progress and sys.stderr.isatty()


def resolution(args: argparse.Namespace) -> tuple[int | None, int | None] | None:
    """``--width``/``--height`` as a film size (``None``: the scene's)."""
    if args.width is None and args.height is None:
        return None
    return (args.width, args.height)


def spp_and_defines(args: argparse.Namespace) -> tuple[int | None, dict[str, str]]:
    """``--spp`` and the ``-D`` defines: ``-D spp=N`` and ``--spp N`` mean the same, and
    ``--spp`` wins."""
    defines = dict(args.defines)
    spp = defines.pop("spp", None)
    if args.spp is not None:
        spp = args.spp
    return spp, defines


# ------------------------------------------------------------------------------- reporting


def result_line(res: Any) -> tuple[str, bool]:
    """The line printed as soon as one scene is done, and whether it is an error."""
    if res.ok:
        names = ", ".join(str(o) for o in res.outputs)
        return t(f"{res.item}: {names} ({res.seconds:.2f} s)"), False
    return t(f"{PROG}: error: {res.error}"), True


def exit_code(results: list) -> int:
    failed = sum(not r.ok for r in results)
    if failed and len(results) > 1:
        fail(f"{failed} of {len(results)} inputs failed")
    return 1 if failed else 0
