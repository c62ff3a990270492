"""Strokes: ordered, typed polylines in film coordinates with exact visibility.

(Method, data model and ambiguities: see the submodules; this docstring is completed below.)
"""

from __future__ import annotations

from .extract import extract_strokes
from .model import KINDS, Stroke, Strokes

__all__ = ["KINDS", "Stroke", "Strokes", "extract_strokes"]
