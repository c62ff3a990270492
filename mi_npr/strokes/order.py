"""Stable orders of integer keys, by one sort of the keys packed with their indices.

``np.argsort(key, kind="stable")`` of int64 keys is a merge sort; ``np.sort`` of int64 values
is numpy's vectorised (SIMD) quicksort, about ten times faster on the topology's and the
raster's arrays. Where a key's range and the index fit in 63 bits together, the key shifted
left past the index bits plus the index sorts into the stable order (equal keys in index
order), and its low bits are that order; otherwise numpy's own stable sort runs.

>>> import numpy as np
>>> stable_argsort(np.array([3, 1, 3, 0, 1])).tolist()
[3, 1, 4, 0, 2]
>>> lexsort_ints((np.array([1, 0, 1, 0]), np.array([2, 2, 1, 1]))).tolist()
[3, 2, 1, 0]
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np


def _span(key: np.ndarray) -> tuple[Any, int]:
    """The least key and the span ``max - min`` (a Python int: no wrap)."""
    lo = key.min()
    return lo, int(key.max()) - int(lo)


def _from_least(key: np.ndarray, lo: Any) -> np.ndarray:
    """``key - lo`` as int64, for a span that fits it (the callers check it): the difference
    taken in int64, or in uint64 for uint64 keys (never negative there), never in a narrow
    type where it would wrap."""
    if key.dtype == np.uint64:
        return (key - lo).astype(np.int64)
    return key.astype(np.int64, copy=False) - int(lo)


def stable_argsort(key: np.ndarray) -> np.ndarray:
    """``np.argsort(key, kind="stable")`` of integer keys ``key`` (N,): the same permutation
    (module docstring)."""
    key = np.asarray(key)
    if key.ndim != 1 or len(key) < 2 or key.dtype.kind not in "iu":
        return np.argsort(key, kind="stable")
    n = len(key)
    lo, span = _span(key)
    bits = (n - 1).bit_length()
    if span >= 1 << (63 - bits):
        return np.argsort(key, kind="stable")
    packed = _from_least(key, lo)  # a new array: worked in place
    packed <<= bits
    packed |= np.arange(n, dtype=np.int64)
    packed.sort()
    packed &= (1 << bits) - 1
    return packed


def lexsort_ints(keys: Sequence[np.ndarray]) -> np.ndarray:
    """``np.lexsort(keys)`` of integer (or boolean) keys (the last the primary, as numpy's):
    the same permutation, through :func:`stable_argsort` of one combined key where the keys'
    spans multiply to less than 2**62, else ``np.lexsort`` itself."""
    keys = [np.asarray(k) for k in keys]
    keys = [k.view(np.uint8) if k.dtype == bool else k for k in keys]
    if (
        not keys
        or any(k.ndim != 1 or k.dtype.kind not in "iu" for k in keys)
        or len({len(k) for k in keys}) != 1
        or len(keys[0]) < 2
    ):
        return np.lexsort(keys)
    spans = [_span(k) for k in keys]
    if math.prod(span + 1 for _, span in spans) >= 1 << 62:
        return np.lexsort(keys)
    combined, total = np.zeros(len(keys[0]), np.int64), 1
    for k, (lo, span) in zip(keys, spans, strict=True):  # the first the least significant
        combined += _from_least(k, lo) * total
        total *= span + 1
    return stable_argsort(combined)
