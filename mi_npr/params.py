"""Parameters: declared once (name, type, default, meaning, check), read from ``mi.Properties``,
keyword arguments or the command line, and rejected with an error that names the plugin (or
flag), the parameter and the value.

One validation table (issue 18): every plugin declares its ``PARAMS`` with :class:`Param`, the
command line's numeric flags are :data:`CLI_PARAMS`, and public functions check their arguments
with :func:`check_arg` against the same rules. Every number must be finite, and every integer
parameter must have a rule with an upper bound (a :class:`Param` of type ``int`` without a check
is refused when it is declared), so no count can make a run hang. ``tests/test81`` is generated
from :func:`all_tables`: each parameter with NaN, inf, negative, zero, huge and wrong-type values.

Mitsuba does not complain about unknown parameters of Python plugins, so a typo such as
``<float name="tt" .../>`` would be silently ignored; :func:`read_props` rejects it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import ParameterError

Rule = Callable[[Any], "str | None"]

#: The largest float32: a float parameter beyond it would be inf in Mitsuba and the kernels.
F32_MAX = 3.4028234663852886e38
#: Largest seed: Mitsuba's samplers take an unsigned 32-bit seed.
SEED_MAX = 2**32 - 1
#: Largest samples per pixel (beyond it a film's sample count overflows long before it helps).
MAX_SPP = 1 << 16
#: Largest image side in pixels (Mitsuba's own limit is far above what memory allows anyway).
MAX_RES = 1 << 15
#: Largest best-view subdivision depth: the triangle's side halves each time; 12 is ~0.02 deg.
MAX_VIEW_DEPTH = 12
#: Most HLPs (and never more than the plant has leaves).
MAX_HLPS = 1024
#: Most selective-dilation passes (it stops changing anything after a few).
MAX_ITERATIONS = 64
#: Most worker processes and Dr.Jit threads per worker of ``mi-npr batch``.
MAX_WORKERS = 1024
MAX_THREADS = 1024
#: Most retries of a failed batch job.
MAX_RETRIES = 100
#: Most views per scene (``orbit:N``, ``sphere:N``, a JSON file of cameras).
MAX_VIEWS = 100_000
#: Most best-view viewpoints (``best:K``): the search rates at most 40 (MAX_EVALUATIONS).
MAX_BEST = 40
#: Deepest ray tree (``npr_raytree``, ``mi-npr raytree --max-depth``).
MAX_RAYTREE_DEPTH = 31
#: Most frames of one camera path (``mi-npr path --frames``; an hour at 25 fps is 90 000).
MAX_FRAMES = 100_000


def integer_range(lo: int, hi: int) -> Rule:
    """The rule of an integer in ``lo..hi``."""

    def check(v: Any) -> str | None:
        return None if lo <= v <= hi else f"must be in {lo}..{hi}"

    return check


def one_of(values: Sequence[str]) -> Rule:
    """The rule of a string among ``values`` (an XML string parameter's choices)."""

    def check(v: Any) -> str | None:
        return None if v in values else f"expected one of {', '.join(values)}"

    return check


def real_range(lo: float, hi: float = math.inf, *, open_lo: bool = False) -> Rule:
    """The rule of a finite number in ``[lo, hi]`` (``(lo, hi]`` with ``open_lo``)."""

    def check(v: Any) -> str | None:
        ok = math.isfinite(v) and (v > lo if open_lo else v >= lo) and v <= hi
        if ok:
            return None
        left = "(" if open_lo else "["
        return f"must be a finite number in {left}{lo:g}, {hi:g}]"

    return check


def rgb_color(rgb: tuple[float, ...]) -> str | None:
    """The rule of a linear RGB colour: three finite values >= 0."""
    ok = all(math.isfinite(v) and v >= 0 for v in rgb)
    return None if ok else "must be finite and >= 0 (linear RGB)"


seed_rule = integer_range(0, SEED_MAX)

Vec3 = tuple[float, float, float]


def check_lookat(
    where: str, origin: Any, target: Any, up: Any, fov: Any
) -> tuple[Vec3, Vec3, Vec3, float | None]:
    """A pinhole camera's ``lookat(origin, target, up)`` and horizontal ``fov`` (degrees;
    ``None`` passes: the sensor's), checked and as floats; errors start with ``where``. The
    one check of every camera a user writes (camera files of ``--views``, camera paths)."""

    def vec3(name: str, value: Any) -> Vec3:
        try:  # a string of three digits is not three numbers
            v = [] if isinstance(value, (str, bytes)) else [float(x) for x in value]
        except (TypeError, ValueError):
            v = []
        if len(v) != 3 or not all(math.isfinite(x) for x in v):
            raise ParameterError(f"{where}: {name} = {value!r}: expected 3 finite numbers")
        return (v[0], v[1], v[2])

    o, t, u = vec3("origin", origin), vec3("target", target), vec3("up", up)
    d = np.subtract(t, o)
    if np.linalg.norm(d) == 0:
        raise ParameterError(f"{where}: origin and target are the same point {list(o)}")
    if np.linalg.norm(np.cross(d, u)) <= 1e-9 * np.linalg.norm(d) * max(np.linalg.norm(u), 1e-30):
        raise ParameterError(f"{where}: up = {list(u)} lies along the view direction (parallel)")
    if fov is not None:
        if isinstance(fov, bool) or not isinstance(fov, (int, float)) or not 0 < fov < 180:
            raise ParameterError(f"{where}: fov = {fov!r}: must be in (0, 180) degrees")
        fov = float(fov)
    return o, t, u, fov


@dataclass(frozen=True)
class Param:
    """One parameter. ``check`` returns an error text for a bad value, else ``None``; integer
    parameters must have one (an upper bound for every count)."""

    name: str
    type: type
    default: Any
    doc: str
    check: Callable[[Any], str | None] | None = None

    def __post_init__(self) -> None:
        if self.type is int and self.check is None:
            raise TypeError(f"Param {self.name!r}: an integer parameter needs a bounded check")


def coerce(plugin: str, p: Param, value: Any) -> Any:
    """Convert ``value`` to ``p.type`` or raise :class:`ParameterError`."""
    bad = f"{plugin}: parameter {p.name!r} = {value!r}"
    if value is None:
        return None
    if isinstance(value, np.generic) and not isinstance(value, (np.str_, np.bytes_)):
        value = value.item()  # numpy scalars count as the Python values they hold
    if p.type is bool:
        if isinstance(value, bool):
            out: Any = value
        elif isinstance(value, str) and value.lower() in ("true", "false", "1", "0"):
            out = value.lower() in ("true", "1")
        else:
            raise ParameterError(f"{bad}: expected a boolean")
    elif p.type is int:
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
            or value != int(value)
        ):
            raise ParameterError(f"{bad}: expected an integer")
        out = int(value)
    elif p.type is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParameterError(f"{bad}: expected a number")
        try:
            out = float(value)
        except OverflowError:
            out = math.inf
        if not abs(out) <= F32_MAX:  # Mitsuba and the kernels read parameters as float32
            raise ParameterError(f"{bad}: must be a finite number (float32)")
    elif p.type is str:
        if not isinstance(value, str):
            raise ParameterError(f"{bad}: expected a string")
        out = value
    elif p.type is tuple:  # an RGB colour
        if isinstance(value, (str, bytes, bool)):
            raise ParameterError(f"{bad}: expected an RGB colour")
        try:
            vals = [float(v) for v in (value if not hasattr(value, "__len__") else list(value))]
        except (TypeError, ValueError, OverflowError):
            raise ParameterError(f"{bad}: expected an RGB colour") from None
        if len(vals) == 1:
            vals = vals * 3
        if len(vals) != 3:
            raise ParameterError(f"{bad}: expected an RGB colour (3 values)")
        if not all(abs(v) <= F32_MAX for v in vals):
            raise ParameterError(f"{bad}: must be finite (linear RGB)")
        out = tuple(vals)
    else:
        out = value
    if p.check is not None:
        problem = p.check(out)
        if problem:
            raise ParameterError(f"{bad}: {problem}")
    return out


def read_props(
    plugin: str, params: Sequence[Param], props: Any, skip: Callable[[Any], bool]
) -> dict[str, Any]:
    """Values of ``params`` from ``props`` (defaults where absent); unknown names are errors.

    ``skip(value)`` tells which properties are not parameters (nested plugins).
    """
    known = {p.name: p for p in params}
    for key in props.keys():
        if key in known:
            continue
        if skip(props.get(key)):
            continue
        names = ", ".join(known) or "none"
        raise ParameterError(f"{plugin}: unknown parameter {key!r} (parameters: {names})")
    return {p.name: coerce(plugin, p, props.get(p.name, p.default)) for p in params}


def check_values(plugin: str, params: Sequence[Param], values: dict[str, Any]) -> dict[str, Any]:
    """Like :func:`read_props` for keyword arguments given from Python."""
    known = {p.name: p for p in params}
    for key in values:
        if key not in known:
            raise ParameterError(
                f"{plugin}: unknown parameter {key!r} (parameters: {', '.join(known)})"
            )
    return {p.name: coerce(plugin, p, values.get(p.name, p.default)) for p in params}


def check_arg(who: str, p: Param, value: Any) -> Any:
    """A public function's argument checked against ``p`` (the same rules as the plugins'):
    the value converted to ``p.type``, or :class:`ParameterError` naming ``who`` and ``p``."""
    return coerce(who, p, value)


def problem(p: Param, value: Any) -> str | None:
    """What is wrong with ``value`` for ``p`` (the text after the name), else ``None``."""
    try:
        coerce("", p, value)
    except ParameterError as e:
        return str(e).split(": ", 2)[-1]
    return None


#: The command line's numeric flags, by command (``mi-npr COMMAND --flag``): parsed with
#: :func:`cli_type` so a bad value is a usage error naming the flag.
#: --width/--height of every command that renders (whatever the scene's <default> names).
_SIZE = (
    Param("--width", int, None, "film width", integer_range(1, MAX_RES)),
    Param("--height", int, None, "film height", integer_range(1, MAX_RES)),
)

#: Where the jobs of mi-npr batch and the frames of mi-npr path run (Dask).
_CLUSTER = (
    Param("--workers", int, None, "worker processes (0: this one)", integer_range(0, MAX_WORKERS)),
    Param(
        "--threads-per-worker",
        int,
        None,
        "Dr.Jit threads per worker",
        integer_range(1, MAX_THREADS),
    ),
    Param("--retries", int, 0, "retries of a failed job", integer_range(0, MAX_RETRIES)),
)

CLI_PARAMS: dict[str, tuple[Param, ...]] = {
    "render": (
        *_SIZE,
        Param("--spp", int, None, "samples per pixel", integer_range(1, MAX_SPP)),
        Param("--seed", int, 0, "sampler seed", seed_rule),
    ),
    "contours": (
        *_SIZE,
        Param("--spp", int, None, "samples per pixel", integer_range(1, MAX_SPP)),
        Param("--seed", int, 0, "sampler seed", seed_rule),
    ),
    "raytree": (
        *_SIZE,
        Param("--spp", int, None, "samples per pixel", integer_range(1, MAX_SPP)),
        Param("--seed", int, 0, "sampler seed", seed_rule),
        Param("--max-depth", int, None, "ray-tree levels", integer_range(1, MAX_RAYTREE_DEPTH)),
    ),
    "best-view": (
        *_SIZE,
        Param("--spp", int, None, "samples per pixel", integer_range(1, MAX_SPP)),
        Param("--depth", int, 3, "levels of subdivision", integer_range(0, MAX_VIEW_DEPTH)),
        Param("--res", int, 128, "ID buffer long side", integer_range(1, MAX_RES)),
    ),
    "batch": (
        *_SIZE,
        Param("--spp", int, None, "samples per pixel", integer_range(1, MAX_SPP)),
        Param("--seed", int, 0, "sampler seed", seed_rule),
        *_CLUSTER,
    ),
    "path": (
        *_SIZE,
        Param("--spp", int, None, "samples per pixel", integer_range(1, MAX_SPP)),
        Param("--seed", int, 0, "sampler seed", seed_rule),
        Param("--frames", int, None, "frames of the path", integer_range(1, MAX_FRAMES)),
        Param("--fps", int, 24, "video frames per second", integer_range(1, 240)),
        Param("--degrees", float, 360.0, "orbit angle", real_range(0.0, 3600.0, open_lo=True)),
        Param("--max-speed", float, 4.0, "degrees per frame", real_range(0.0, 180.0, open_lo=True)),
        Param("--max-turn", float, 12.0, "degrees per frame", real_range(0.0, 180.0, open_lo=True)),
        *_CLUSTER,
    ),
    "foliage": (
        Param("--leaf-size", float, None, "leaf length", real_range(0.0, 1e6, open_lo=True)),
        Param("--abstraction", float, None, "normal mixing", real_range(0.0, 1.0)),
        Param("--hlps", int, None, "number of HLPs", integer_range(1, MAX_HLPS)),
        Param("--seed", int, 0, "seed", seed_rule),
    ),
}


#: The counts inside ``mi-npr batch --views SPEC`` (``orbit:N``, ``sphere:N``, ``best:K``, the
#: cameras of a JSON file): checked like flags (:mod:`mi_npr.views`).
VIEW_PARAMS: tuple[Param, ...] = (
    Param("orbit", int, 8, "views on the orbit", integer_range(1, MAX_VIEWS)),
    Param("sphere", int, 8, "views on the viewing sphere", integer_range(1, MAX_VIEWS)),
    Param("best", int, 1, "best-rated views", integer_range(1, MAX_BEST)),
    Param("file", int, 1, "cameras in a JSON file", integer_range(1, MAX_VIEWS)),
)


def cli_param(command: str, flag: str) -> Param:
    """The :data:`CLI_PARAMS` entry of ``flag`` of ``command``."""
    return next(p for p in CLI_PARAMS[command] if p.name == flag)


def cli_type(command: str, flag: str) -> Callable[[str], Any]:
    """An ``argparse`` ``type=`` that parses ``flag``'s text and checks it against its table
    entry; a bad value raises ``ArgumentTypeError`` (argparse names the flag)."""
    import argparse

    p = cli_param(command, flag)

    def parse(text: str) -> Any:
        try:
            value: Any = int(text) if p.type is int else float(text)
        except ValueError:
            kind = "an integer" if p.type is int else "a number"
            raise argparse.ArgumentTypeError(f"{text!r} is not {kind}") from None
        why = problem(p, value)
        if why:
            raise argparse.ArgumentTypeError(f"{text!r}: {why}")
        return coerce(flag, p, value)

    return parse


def all_tables() -> dict[str, tuple[Param, ...]]:
    """Every parameter table: each plugin's ``PARAMS`` (module- or class-level), the lines
    chain's and the command line's (for the generated test, so no parameter escapes it)."""
    import importlib
    import pkgutil

    from . import plugins as plugin_pkg
    from .kernels import LINES_PARAMS

    tables: dict[str, tuple[Param, ...]] = {"lines": LINES_PARAMS}
    for info in pkgutil.iter_modules(plugin_pkg.__path__):
        mod = importlib.import_module(f"{plugin_pkg.__name__}.{info.name}")
        found = [getattr(mod, "PARAMS", None)]
        found += [getattr(v, "PARAMS", None) for v in vars(mod).values() if isinstance(v, type)]
        for t in found:
            if t and all(isinstance(p, Param) for p in t):
                tables[info.name] = tuple(dict.fromkeys([*tables.get(info.name, ()), *t]))
    for cmd, t in CLI_PARAMS.items():
        tables[f"mi-npr {cmd}"] = t
    tables["mi-npr batch --views"] = VIEW_PARAMS
    return tables
