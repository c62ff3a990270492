"""Plugin parameters: declared once (name, type, default, meaning, check), read from
``mi.Properties``, and rejected with an error that names the plugin, the parameter and the value.

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


@dataclass(frozen=True)
class Param:
    """One plugin parameter. ``check`` returns an error text for a bad value, else ``None``."""

    name: str
    type: type
    default: Any
    doc: str
    check: Callable[[Any], str | None] | None = None


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
        out = float(value)
    elif p.type is str:
        if not isinstance(value, str):
            raise ParameterError(f"{bad}: expected a string")
        out = value
    elif p.type is tuple:  # an RGB colour
        try:
            vals = [float(v) for v in (value if not hasattr(value, "__len__") else list(value))]
        except (TypeError, ValueError):
            raise ParameterError(f"{bad}: expected an RGB colour") from None
        if len(vals) == 1:
            vals = vals * 3
        if len(vals) != 3:
            raise ParameterError(f"{bad}: expected an RGB colour (3 values)")
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


def table(params: Sequence[Param]) -> str:
    """The parameter table of a plugin's manual (reStructuredText, like Mitsuba's docs)."""
    rows = [
        (p.name, "rgb" if p.type is tuple else p.type.__name__, repr(p.default), p.doc)
        for p in params
    ]
    return "\n".join(f"  {a:<22} {b:<7} {c:<10} {d}" for a, b, c, d in rows)
