"""The batch manifest ``OUT/manifest.jsonl`` and the content hash of a scene.

One JSON object per line, one line per finished or failed job, appended by one process (the
batch's client) with ``O_APPEND`` and a single ``write()`` of the whole line followed by
``fsync``: a line is in the file whole or not at all, and lines of concurrent writers never
interleave. A reader skips a line that does not parse (a disk that filled mid-line), so a
manifest is always readable; the last line of a job wins.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from ..errors import OutputError, ParameterError
from ..scene import scene_files

MANIFEST = "manifest.jsonl"


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
    if os.path.lexists(path):
        try:
            mode = os.stat(path).st_mode
        except OSError as e:
            raise OutputError(f"{path}: cannot read the manifest ({e.strerror})") from None
        if not stat.S_ISREG(mode):
            raise OutputError(f"{path}: not a regular file")


def append_row(path: str | os.PathLike[str], row: Mapping[str, Any]) -> None:
    """Append ``row`` as one JSON line to ``path`` atomically (module docstring)."""
    data = (json.dumps(row, sort_keys=True, allow_nan=False, default=str) + "\n").encode()
    fd = _open_regular(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, "write")
    try:
        n = os.write(fd, data)
        if n != len(data):  # a full disk: the reader skips the partial line
            raise OutputError(f"{path}: manifest line cut short (disk full?)")
        os.fsync(fd)
    except OSError as e:
        raise OutputError(f"{path}: cannot write the manifest ({e.strerror})") from None
    finally:
        os.close(fd)


def read_rows(path: str | os.PathLike[str]) -> Iterator[dict[str, Any]]:
    """The rows of a manifest in file order (none if it does not exist); bad lines skipped."""
    try:
        f = os.fdopen(_open_regular(path, os.O_RDONLY, "read"), "rb")
    except FileNotFoundError:
        return
    with f:
        for line in f:
            try:
                row = json.loads(line)
            except (json.JSONDecodeError, UnicodeDecodeError):
                continue
            if isinstance(row, dict):
                yield row


def scene_hash(path: str | os.PathLike[str], defines: Mapping[str, Any] | None = None) -> str:
    """SHA-256 of a scene file and of every file it references with ``defines``
    (:func:`mi_npr.scene.scene_files`: meshes, textures, includes, ``$name`` resolved), in
    document order, each with its name relative to the scene: ``sha256:<hex>``. A referenced
    file that does not exist counts by its name only."""
    xml = Path(path).resolve()
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
