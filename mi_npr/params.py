"""Parameters: declared once (name, type, default, meaning, check), read from ``mi.Properties``,
keyword arguments or the command line, and rejected with an error that names the plugin (or
function), the parameter and the value.

This module is the type and its checks; it knows no drawing and no command-line flag. A table
(a tuple of :class:`Param`) is owned by the library module whose functions check their
arguments against it with :func:`check_arg`: each drawing's (:mod:`mi_npr.drawings`), the
render settings (:data:`mi_npr.scene.RENDER_PARAMS`), the batch's, the path's, best view's
and the foliage's; the command line builds its flags from them. Every number must be finite,
and every integer parameter must have a rule with an upper bound (a :class:`Param` of type
``int`` without a check is refused when it is declared), so no count can make a run hang.

Mitsuba does not complain about unknown parameters of Python plugins, so a typo such as
``<float name="tt" .../>`` would be silently ignored; :func:`read_props` rejects it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import ParameterError, shown

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


def names(what: str, value: Any) -> tuple[str, ...]:
    """``value`` as a tuple of names (a list or tuple of ``str``), or :class:`ParameterError`
    naming ``what``: a lone string is one name spelt out letter by letter, not a list."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple, set, frozenset)):
        raise ParameterError(f"{what} = {shown(value)}: expected a list of names")
    bad = [v for v in value if not isinstance(v, str)]
    if bad:
        raise ParameterError(f"{what}: {shown(bad[0])} is not a name")
    return tuple(value)


def name_list(what: str, value: Any) -> tuple[str, ...]:
    """:func:`names`, where a lone string is one name (``ignore="floor"``)."""
    return (value,) if isinstance(value, str) else names(what, value)


def coerce(plugin: str, p: Param, value: Any) -> Any:
    """Convert ``value`` to ``p.type`` or raise :class:`ParameterError`."""
    bad = f"{plugin}: parameter {p.name!r} = {shown(value)}"
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


def entry(table: Sequence[Param], name: str) -> Param:
    """The parameter ``name`` of ``table``."""
    for p in table:
        if p.name == name:
            return p
    raise KeyError(name)


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
