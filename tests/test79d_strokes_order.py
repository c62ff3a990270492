"""The strokes' integer sorts (``mi_npr.strokes.order``) against numpy's own stable sorts."""

from __future__ import annotations

import numpy as np
import pytest

from mi_npr.strokes.order import lexsort_ints, stable_argsort

RNG = np.random.default_rng(79)


def _keys(dtype: str, n: int, span: int) -> np.ndarray:
    info = np.iinfo(dtype)
    lo = max(int(info.min), -span // 2) if info.min < 0 else 0
    return RNG.integers(lo, min(int(info.max), lo + span), n, endpoint=True).astype(dtype)


@pytest.mark.parametrize("dtype", ["int8", "uint8", "int32", "uint32", "int64", "uint64"])
@pytest.mark.parametrize("n", [0, 1, 2, 3, 17, 1000, 65537])
@pytest.mark.parametrize("span", [0, 1, 5, 1 << 20, 1 << 40])
def test01_stable_argsort_is_numpys(dtype, n, span):
    key = _keys(dtype, n, span)
    assert np.array_equal(stable_argsort(key), np.argsort(key, kind="stable"))


@pytest.mark.parametrize(
    "key",
    [
        # spans too wide to pack with the index: numpy's own sort
        np.array([np.iinfo(np.int64).max, np.iinfo(np.int64).min, 0, 0, -1]),
        np.array([np.iinfo(np.uint64).max, 0, 3, np.iinfo(np.uint64).max - 1], np.uint64),
        np.array([2**62, 0, 2**62, 1]),
        # near the top of uint64 but a narrow span: packed, from the least key
        np.array([2**64 - 1, 2**64 - 3, 2**64 - 1, 2**64 - 2], np.uint64),
        # floats and booleans: numpy's own
        np.array([0.5, -0.0, 0.0, np.nan, 0.5, -np.inf]),
        np.array([True, False, True, False]),
    ],
)
def test02_wide_spans_and_other_kinds(key):
    assert np.array_equal(stable_argsort(key), np.argsort(key, kind="stable"))


def test03_random_spans_at_the_packing_limit():
    """Spans on either side of the last one that packs with the indices' bits."""
    for n in (2, 3, 1000, 4096, 4097):
        bits = (n - 1).bit_length()
        for span in ((1 << (63 - bits)) - 1, 1 << (63 - bits)):
            key = RNG.integers(0, span, n, endpoint=True, dtype=np.int64) - (span // 3)
            key[:2] = [-(span // 3), span - span // 3]  # the whole span present
            assert np.array_equal(stable_argsort(key), np.argsort(key, kind="stable"))


@pytest.mark.parametrize("n", [0, 1, 2, 9, 5000])
def test04_lexsort_ints_is_numpys(n):
    keys = (
        RNG.integers(-3, 3, n),
        RNG.integers(0, 2, n).astype(bool),
        RNG.integers(0, 1 << 30, n).astype(np.uint32),
        RNG.integers(-(1 << 40), 1 << 40, n),
    )
    for k in range(1, len(keys) + 1):
        assert np.array_equal(lexsort_ints(keys[:k]), np.lexsort(keys[:k]))


def test05_lexsort_ints_too_wide_or_not_integers():
    n = 3000
    wide = (RNG.integers(0, 1 << 40, n), RNG.integers(0, 1 << 40, n))  # 80 bits together
    assert np.array_equal(lexsort_ints(wide), np.lexsort(wide))
    mixed = (RNG.random(n), RNG.integers(0, 4, n))
    assert np.array_equal(lexsort_ints(mixed), np.lexsort(mixed))
    ties = (np.zeros(n, np.int64), np.ones(n, np.int64))  # every key equal: index order
    assert np.array_equal(lexsort_ints(ties), np.arange(n))
