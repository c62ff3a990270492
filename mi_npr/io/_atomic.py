"""Atomic writes: every output goes to a temporary name in the target directory and is renamed
into place only once complete, so a crash or a bad input never leaves a half-written file.

Temporary names carry the writing process's PID and :data:`OWNER`, a digest of its host name
and PID namespace (``.NAME.PID.OWNER.XXXXXXXX.tmp``); they are removed on every exit path
(exceptions, ``atexit``, SIGTERM through the CLI), and those of a run that was killed outright
(SIGKILL) are swept by the next run that writes to the same directory, only when certainly
stale: written on this host in this PID namespace by a PID that is gone, or untouched for
:data:`STALE_AFTER` seconds whoever wrote them. A PID of another host or container means
nothing here (on the shared storage of a cluster, or in containers, that PID may be a live
writer), so such a file, and a name of an older version without the owner, waits for the age
bound. :func:`output_set` replaces a set of outputs (EXR, PNGs, SVG, XML) all together or not
at all.
"""

from __future__ import annotations

import atexit
import contextlib
import hashlib
import os
import re
import socket
import stat
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path

from ..errors import OutputError, as_path, one_line


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


# mkstemp creates files readable by their owner only; outputs get the usual permissions.
_FILE_MODE = 0o666 & ~_umask()


def check_writable_dir(directory: str | os.PathLike[str], create: bool = False) -> Path:
    """``directory`` as a Path, created if asked; :class:`OutputError` if it cannot be written
    (an empty name too: it is no folder, not the current one)."""
    if isinstance(directory, str) and not directory:
        raise OutputError("output directory '': an empty name (give a folder, e.g. -o out)")
    d = as_path(directory, "output directory", OutputError)
    if create:
        try:
            d.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise OutputError(f"{d}: cannot create output directory ({e.strerror})") from None
    if not d.is_dir():
        raise OutputError(f"{d}: output directory does not exist")
    if not os.access(d, os.W_OK | os.X_OK):
        raise OutputError(f"{d}: output directory is not writable")
    return d


def _check_target(target: Path) -> None:
    """:class:`OutputError` when ``target`` exists and is not a regular file (or a link to
    one): a FIFO, a device or a socket is never replaced by an output."""
    try:
        mode = os.stat(target).st_mode
    except OSError:
        return  # nothing there (or a dangling link): the rename creates the file
    if stat.S_ISDIR(mode):
        raise OutputError(f"{target}: is a directory")
    if not stat.S_ISREG(mode):
        raise OutputError(f"{target}: not a regular file")


def _owner() -> str:
    try:
        namespace = os.readlink("/proc/self/ns/pid")
    except OSError:
        namespace = ""
    return hashlib.sha256(f"{socket.gethostname()}\0{namespace}".encode()).hexdigest()[:12]


#: This host and PID namespace, as 12 hex digits in every temporary name (module docstring).
OWNER = _owner()
#: Seconds after which a temporary file is stale whoever wrote it: a live writer renames its
#: files when its output set is complete, seconds after writing them.
STALE_AFTER = 3600.0

#: This process's temporary files not yet renamed into place (removed at exit, on SIGTERM).
_LIVE: set[str] = set()
#: Held from a temporary file's creation to its entry in :data:`_LIVE`, and by a sweep from
#: its look into :data:`_LIVE` to the removal: a sweep in one thread never takes the file
#: another thread has just created for itself as a leftover of this process.
_LIVE_LOCK = threading.RLock()
#: Open output sets (:func:`output_set`) of each thread, innermost last: their (temp, target)
#: pairs (a thread's files never join another thread's set).
_THREAD = threading.local()
#: Directories already swept for stale temporary files by this process.
_SWEPT: set[str] = set()
# ".NAME.PID.OWNER.XXXXXXXX.tmp" (this version), ".NAME.PID.XXXXXXXX.tmp" and
# ".NAME.XXXXXXXX.tmp" (older versions).
_TEMP = re.compile(
    r"^\.(?P<name>.+?)\.(?:(?P<pid>\d+)\.(?:(?P<owner>[0-9a-f]{12})\.)?)?"
    r"(?P<rand>[a-z0-9_]{8})\.tmp$"
)


def temp_name_pid(name: str) -> int | bool | None:
    """The PID in a temporary file name of this tool, ``None`` for an old name without one, or
    ``False`` when ``name`` is not one of ours."""
    m = _TEMP.match(name)
    if not m:
        return False
    return int(m["pid"]) if m["pid"] else None


def temp_name_owner(name: str) -> str | None:
    """The :data:`OWNER` in a temporary file name of this tool (``None``: an older name, or
    not one of ours)."""
    m = _TEMP.match(name)
    return m["owner"] if m else None


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return True  # someone else's process (or not a PID we can ask about): keep its files
    return True


def clean_stale(directory: str | os.PathLike[str]) -> list[Path]:
    """Remove this tool's temporary files in ``directory`` that are certainly stale (module
    docstring): this host and PID namespace's whose PID is gone (or is this process, which
    does not use them), and any untouched for :data:`STALE_AFTER` seconds. Returns what was
    removed; errors are ignored (best effort)."""
    removed: list[Path] = []
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return removed
    for e in entries:
        pid = temp_name_pid(e.name)
        if pid is False:
            continue
        with _LIVE_LOCK:
            if e.path in _LIVE:
                continue
            try:
                if not e.is_file(follow_symlinks=False):
                    continue
                ours = pid is not None and temp_name_owner(e.name) == OWNER
                stale = (not _alive(pid) or pid == os.getpid()) if ours else False
                if stale or time.time() - e.stat(follow_symlinks=False).st_mtime >= STALE_AFTER:
                    os.unlink(e.path)
                    removed.append(Path(e.path))
            except OSError:
                continue
    return removed


def remove_live_temps() -> None:
    """Remove every temporary file of this process that was not renamed (exit, SIGTERM)."""
    with _LIVE_LOCK:
        for tmp in list(_LIVE):
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            _LIVE.discard(tmp)


atexit.register(remove_live_temps)


def _sets() -> list[list[tuple[str, Path]]]:
    """This thread's open output sets."""
    if not hasattr(_THREAD, "sets"):
        _THREAD.sets = []
    return _THREAD.sets


@contextlib.contextmanager
def output_set() -> Iterator[None]:
    """Every :func:`atomic_output` inside the block is renamed into place at its end, all
    together, or none of them (their temporary files removed) if the block fails: an output set
    (EXR, PNGs, SVG, XML) never mixes two runs. Nested sets join the outermost one."""
    sets = _sets()
    batch: list[tuple[str, Path]] = []
    sets.append(batch)
    try:
        yield
    except BaseException:
        sets.pop()
        for tmp, _ in batch:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            _LIVE.discard(tmp)
        raise
    sets.pop()
    if sets:
        sets[-1].extend(batch)
        return
    try:
        for tmp, target in batch:
            os.replace(tmp, target)
            _LIVE.discard(tmp)
    except OSError as e:
        raise OutputError(f"{target}: cannot write ({e.strerror or e})") from None
    finally:
        for tmp, _ in batch:
            if tmp in _LIVE:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
                _LIVE.discard(tmp)


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike[str]) -> Iterator[str]:
    """Yield a temporary path beside ``path``; rename it to ``path`` if the block succeeds
    (inside an :func:`output_set`, at the set's end). The temporary name is
    ``.NAME.PID.OWNER.XXXXXXXX.tmp``; stale ones of killed runs are swept from the directory
    first."""
    target = Path(path)
    parent = target.parent if str(target.parent) else Path(".")
    check_writable_dir(parent)
    _check_target(target)
    key = os.path.realpath(parent)
    with _LIVE_LOCK:
        sweep = key not in _SWEPT
        _SWEPT.add(key)
    if sweep:
        clean_stale(parent)
    with _LIVE_LOCK:  # created and listed as live before any sweep can look at it
        try:
            fd, tmp = tempfile.mkstemp(
                prefix=f".{target.name}.{os.getpid()}.{OWNER}.", suffix=".tmp", dir=parent
            )
        except OSError as e:
            raise OutputError(f"{target}: cannot write ({e.strerror or e})") from None
        _LIVE.add(tmp)
    os.close(fd)
    deferred = False
    sets = _sets()
    try:
        yield tmp
        os.chmod(tmp, _FILE_MODE)
        if sets:
            sets[-1].append((tmp, target))
            deferred = True
        else:
            os.replace(tmp, target)
    except OSError as e:
        raise OutputError(f"{target}: cannot write ({e.strerror or e})") from None
    except RuntimeError as e:  # OpenEXR reports I/O failures (a full disk) as RuntimeError
        raise OutputError(f"{target}: cannot write ({one_line(e)})") from None
    finally:
        if not deferred:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
            _LIVE.discard(tmp)
