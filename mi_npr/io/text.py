"""Text outputs (XML snippets, JSON), written atomically like every other output."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import ParameterError, as_path, shown
from ._atomic import atomic_output


def quoteattr(value: str) -> str:
    """``value`` as a double-quoted XML attribute value (``&``, ``<``, ``>``, ``"`` and the
    whitespace that attribute normalisation would eat escaped). What
    ``xml.sax.saxutils.quoteattr`` gives, without its import (it pulls in urllib, http and ssl
    at every process start)."""
    for a, b in (("&", "&amp;"), ("<", "&lt;"), (">", "&gt;"), ('"', "&quot;")):
        value = value.replace(a, b)
    for a, b in (("\n", "&#10;"), ("\r", "&#13;"), ("\t", "&#9;")):
        value = value.replace(a, b)
    return f'"{value}"'


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through a temporary file; returns the path."""
    target = as_path(path, "output file")
    if not isinstance(text, str):
        raise ParameterError(f"text = {shown(text)}: expected a str")
    with atomic_output(target) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return target
