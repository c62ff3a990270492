"""Atomic writes: every output goes to a temporary name in the target directory and is renamed
into place only once complete, so a crash or a bad input never leaves a half-written file."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from ..errors import OutputError, one_line


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


# mkstemp creates files readable by their owner only; outputs get the usual permissions.
_FILE_MODE = 0o666 & ~_umask()


def check_writable_dir(directory: str | os.PathLike[str], create: bool = False) -> Path:
    """``directory`` as a Path, created if asked; :class:`OutputError` if it cannot be written."""
    d = Path(directory)
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


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike[str]) -> Iterator[str]:
    """Yield a temporary path beside ``path``; rename it to ``path`` if the block succeeds."""
    target = Path(path)
    check_writable_dir(target.parent if str(target.parent) else ".")
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, _FILE_MODE)
        os.replace(tmp, target)
    except OSError as e:
        raise OutputError(f"{target}: cannot write ({e.strerror or e})") from None
    except RuntimeError as e:  # OpenEXR reports I/O failures (a full disk) as RuntimeError
        raise OutputError(f"{target}: cannot write ({one_line(e)})") from None
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
