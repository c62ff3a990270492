"""The batch manifest ``OUT/manifest.jsonl`` and the content hash of a scene.

One JSON object per line, one line per finished or failed job, appended by one process (the
batch's client) with ``O_APPEND`` and a single ``write()`` of the whole line: a line is in the
file whole or not at all, and lines of concurrent writers never interleave. A line cut short
(a disk that filled mid-line) ends without a newline; the next row written starts with one, so
it is never glued onto the cut line. A reader skips a line that does not parse, or whose fields
have the wrong types (:data:`FIELDS`), with a warning naming the line, so a manifest is always
readable; the last line of a job wins.

**What survives what.** A row is in the file (the kernel's page cache) when
:func:`append_row` returns, before the batch counts its job as recorded: a process killed at
any moment, ``SIGKILL`` included, loses no recorded row. ``fsync``, needed only to survive a
power loss or a crash of the machine, follows every row of :func:`append_row` alone. A batch
appends through an :class:`Appender`, which ``fsync``-s a row at once when the last ``fsync``
is :data:`SYNC_INTERVAL` seconds old or more, else with the next such row or at the batch's
end: after a power loss, the rows written since the last ``fsync`` may be missing (as may the
output files, which are never ``fsync``-ed), and resume runs their jobs again.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import math
import os
import stat
import time
import warnings
from collections.abc import Iterator, Mapping
from typing import Any

from ..errors import NprWarning, OutputError, ParameterError, as_path
from ..scene import scene_files

MANIFEST = "manifest.jsonl"

_OPTIONAL_STR = (str, type(None))
#: The types of a row's fields (a field may be absent; ``outputs`` and ``retried`` hold
#: strings, ``sizes`` integers; ``bool`` is no integer here).
FIELDS: dict[str, tuple[type, ...]] = {
    "job": (str,),
    "status": (str,),
    "key": (str,),
    "version": (str,),
    "scene": (str,),
    "scene_hash": (str,),
    "view": (str,),
    "outputs": (list,),
    "sizes": (list,),
    "retried": (list,),
    "attempt": (int,),
    "seconds": (int, float, type(None)),
    "error": _OPTIONAL_STR,
    "warning": _OPTIONAL_STR,
    "worker": _OPTIONAL_STR,
    "finished": _OPTIONAL_STR,
    "camera": (dict, type(None)),
    "flags": (dict,),
}
_ITEMS = {"outputs": str, "retried": str, "sizes": int}


def row_problem(row: Any) -> str | None:
    """Why ``row`` is no manifest row (:data:`FIELDS`), or ``None``."""
    if not isinstance(row, dict):
        return f"a {type(row).__name__}, not an object"
    if "job" not in row:
        return "no 'job'"
    for name, types in FIELDS.items():
        if name not in row:
            continue
        v = row[name]
        if isinstance(v, bool) or not isinstance(v, types):
            return f"{name!r} is a {type(v).__name__}"
        item = _ITEMS.get(name)
        if item is not None and not all(isinstance(x, item) and not isinstance(x, bool) for x in v):
            return f"{name!r} holds something other than {item.__name__}s"
    return None


def _open_regular(path: str | os.PathLike[str], flags: int, what: str) -> int:
    """``os.open`` that never blocks on a FIFO (``O_NONBLOCK``) and refuses anything but a
    regular file: :class:`OutputError` "not a regular file" (a FIFO, device or socket)."""
    try:
        fd = os.open(path, flags | os.O_NONBLOCK, 0o666)
    except FileNotFoundError:
        raise
    except OSError as e:  # a FIFO without a reader: ENXIO
        check_manifest(path)
        raise OutputError(f"{path}: cannot {what} the manifest ({e.strerror})") from None
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise OutputError(f"{path}: not a regular file")
    os.set_blocking(fd, True)
    return fd


def check_manifest(path: str | os.PathLike[str]) -> None:
    """:class:`OutputError` when ``path`` exists and is not a regular file (checked before a
    batch renders anything, so no job's work is lost to an unwritable manifest)."""
    path = as_path(path, "manifest")
    if os.path.lexists(path):
        try:
            mode = os.stat(path).st_mode
        except OSError as e:
            raise OutputError(f"{path}: cannot read the manifest ({e.strerror})") from None
        if not stat.S_ISREG(mode):
            raise OutputError(f"{path}: not a regular file")


def append_row(path: str | os.PathLike[str], row: Mapping[str, Any], *, sync: bool = True) -> None:
    """Append ``row`` as one JSON line to ``path`` atomically, and ``fsync`` it when ``sync``
    (module docstring)."""
    data = (json.dumps(row, sort_keys=True, allow_nan=False, default=str) + "\n").encode()
    fd = _open_regular(path, os.O_RDWR | os.O_APPEND | os.O_CREAT, "write")
    try:
        # Locked, so that the last byte read is that of a whole line of another writer, never
        # of one still being copied in (where locks are not supported, the one client is the
        # only writer anyway).
        with contextlib.suppress(OSError):
            fcntl.lockf(fd, fcntl.LOCK_EX)
        size = os.fstat(fd).st_size
        if size and os.pread(fd, 1, size - 1) != b"\n":  # a line cut short: start a new one
            data = b"\n" + data
        n = os.write(fd, data)
        if n != len(data):  # a full disk: the reader skips the partial line
            raise OutputError(f"{path}: manifest line cut short (disk full?)")
        if sync:
            os.fsync(fd)
    except OSError as e:
        raise OutputError(f"{path}: cannot write the manifest ({e.strerror})") from None
    finally:
        os.close(fd)


#: Seconds between two ``fsync`` of a batch's manifest (:class:`Appender`).
SYNC_INTERVAL = 1.0


class Appender:
    """A batch's rows appended to its manifest (:func:`append_row`), each written as it comes,
    ``fsync``-ed at most once every :data:`SYNC_INTERVAL` seconds and by :meth:`close` (module
    docstring)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = path
        self._synced = -math.inf  # time.monotonic() of the last fsync
        self._pending = False  # rows written since

    def append(self, row: Mapping[str, Any]) -> None:
        now = time.monotonic()
        due = now - self._synced >= SYNC_INTERVAL
        append_row(self.path, row, sync=due)
        if due:
            self._synced, self._pending = now, False
        else:
            self._pending = True

    def close(self) -> None:
        """``fsync`` the rows written since the last one (none: nothing to do)."""
        if not self._pending:
            return
        self._pending = False
        try:
            fd = _open_regular(self.path, os.O_WRONLY | os.O_APPEND, "write")
        except FileNotFoundError:  # removed meanwhile: nothing of it to keep
            return
        try:
            os.fsync(fd)
        except OSError as e:
            raise OutputError(f"{self.path}: cannot write the manifest ({e.strerror})") from None
        finally:
            os.close(fd)
        self._synced = time.monotonic()


def read_rows(path: str | os.PathLike[str]) -> Iterator[dict[str, Any]]:
    """The rows of a manifest in file order (none if it does not exist); a line that does not
    parse or is no row (:func:`row_problem`) is skipped with a
    :class:`~mi_npr.errors.NprWarning` naming it (``manifest.jsonl:7: ...``)."""
    try:
        f = os.fdopen(_open_regular(path, os.O_RDONLY, "read"), "rb")
    except FileNotFoundError:
        return
    with f:
        for number, line in enumerate(f, 1):
            if not line.strip():
                continue
            try:
                row = json.loads(line)
                why = row_problem(row)
            except (ValueError, RecursionError) as e:  # RecursionError: nesting too deep
                why = f"not JSON ({type(e).__name__})"
            if why is None:
                yield row
            else:
                warnings.warn(f"{path}:{number}: row skipped: {why}", NprWarning, stacklevel=2)


def scene_hash(path: str | os.PathLike[str], defines: Mapping[str, Any] | None = None) -> str:
    """SHA-256 of a scene file and of every file it references with ``defines``
    (:func:`mi_npr.scene.scene_files`: meshes, textures, includes, ``$name`` resolved), in
    document order, each with its name relative to the scene: ``sha256:<hex>``. A referenced
    file that does not exist counts by its name only."""
    xml = as_path(path, "scene file").resolve()
    h = hashlib.sha256()
    try:
        files = [xml, *scene_files(xml, defines)]
        for f in files:
            rel = os.path.relpath(f, xml.parent) if f != xml else ""
            h.update(rel.encode() + b"\0")
            if f != xml and not f.is_file():
                h.update(b"missing\0")
                continue
            with open(f, "rb") as fh:
                for block in iter(lambda fh=fh: fh.read(1 << 20), b""):
                    h.update(block)
            h.update(b"\0")
    except OSError as e:
        raise ParameterError(f"{path}: cannot read the scene ({e.strerror})") from None
    return "sha256:" + h.hexdigest()
