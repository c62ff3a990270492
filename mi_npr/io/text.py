"""Text outputs (XML snippets, JSON), written atomically like every other output."""

from __future__ import annotations

import os
from pathlib import Path

from ._atomic import atomic_output


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through a temporary file; returns the path."""
    target = Path(path)
    with atomic_output(target) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return target
