"""The errors mi-npr raises on bad input: one line each, naming the file, parameter or value.

The CLI prints ``str(error)`` and exits with code 1 (or 2 for usage errors); a traceback is a bug.
"""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path


class NprError(Exception):
    """Base class of every error mi-npr raises on purpose. Its text is one line: line breaks
    in a message (a value's multi-line ``repr``, a library's message) become spaces."""

    def __str__(self) -> str:
        return " ".join(super().__str__().split())


class SceneError(NprError):
    """A scene cannot be loaded or rendered (missing file, malformed XML, Mitsuba error)."""


class ParameterError(NprError, ValueError):
    """A parameter has a bad value; the message names the parameter and the value."""


class InputError(NprError):
    """An input file (EXR, mesh, ...) cannot be read or holds something unexpected."""


class MemoryLimitError(NprError):
    """A render would need more memory than the process may use (see :mod:`mi_npr.memory`)."""


class OutputError(NprError):
    """An output cannot be written (directory missing or not writable, disk full, ...)."""


class NprWarning(UserWarning):
    """A warning mi-npr gives on purpose, one line; the command line prints it as
    ``mi-npr: warning: ...``."""


def one_line(exc: BaseException) -> str:
    """Mitsuba's messages span lines and start with ``[file.cpp:123]``: keep the useful part."""

    text = str(exc).strip() or type(exc).__name__
    marker = "Traceback (most recent call last):"
    if marker in text:
        # A Python plugin raised inside Mitsuba's loader: keep where, and the exception's message.
        head, _, tail = text.partition(marker)
        lines = [ln.strip() for ln in tail.splitlines() if ln.strip()]
        last = re.sub(r"^[\w.]*(?:Error|Exception)\b:\s*", "", lines[-1]) if lines else ""
        text = f"{head.strip()} {last}".strip()
    text = re.sub(r"\[[\w./-]+\.(?:cpp|h|py):\d+\]\s*", "", text)
    text = " ".join(part.strip() for part in text.splitlines() if part.strip())
    return text


def shown(value: object, limit: int = 60) -> str:
    """``repr(value)`` on one line and at most ``limit`` characters, for messages that name a
    bad value (an array's ``repr`` spans lines and pages).

    >>> shown([1, 2])
    '[1, 2]'
    >>> shown("x" * 100, 10)
    "'xxxxxx..."
    """
    text = " ".join(repr(value).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def as_path(value: object, what: str = "path", error: type[NprError] = ParameterError) -> Path:
    """``value`` as a Path if it names one (a ``str`` or ``os.PathLike``, not empty), else
    ``error`` naming ``what`` and the value: ``None``, a number or a list is no file name."""
    if isinstance(value, (str, os.PathLike)):
        text = os.fspath(value)
        if isinstance(text, str) and text:
            return Path(text)
    raise error(f"{what} = {shown(value)}: expected a file name (str or path)")


def check_input_file(path: str | os.PathLike[str], error: type[NprError] = InputError) -> Path:
    """``path`` as a Path if it is a readable regular file, else ``error`` with the reason:
    "no such file", "is a directory", "not a regular file" (a device, a FIFO, a socket) or
    "permission denied". One place for every input file (scenes, EXRs, meshes, HLPs)."""
    p = as_path(path, "input file", error)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise error(f"{p}: no such file") from None
    except NotADirectoryError:
        raise error(f"{p}: no such file (a parent is not a directory)") from None
    except OSError as e:
        raise error(f"{p}: cannot read ({e.strerror or e})") from None
    if stat.S_ISDIR(st.st_mode):
        raise error(f"{p}: is a directory")
    if not stat.S_ISREG(st.st_mode):
        raise error(f"{p}: not a regular file")
    if not os.access(p, os.R_OK):
        raise error(f"{p}: permission denied")
    return p


def for_terminal(text: object) -> str:
    """``text`` with control characters escaped (``\\x1b``, ``\\n``, ``\\u202e``...), for
    everything that reaches a terminal: names from scenes and files (object ids, layer names,
    metadata, paths) could otherwise set the terminal's title and colours or split a listing.
    The one helper for it."""
    s = str(text)
    if s.isprintable():
        return s
    return "".join(ch if ch.isprintable() else ch.encode("unicode_escape").decode() for ch in s)
