"""The O(N) ratio selection is the stable sort's selection: same mask, same τ (bits included)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from harness.core import ratios
from methods.targeting import removal_count, select_by_keep, select_by_ratio


def sorted_selection(scores, ratio):
    """The rule as first written: a stable argsort on (score, index), the first k removed."""
    scores = np.asarray(scores, dtype=np.float64)
    k = removal_count(len(scores), ratio)
    order = np.argsort(scores, kind="stable")
    keep = np.ones(len(scores), dtype=bool)
    keep[order[:k]] = False
    return keep, (float(scores[order[k - 1]]) if k > 0 else float("-inf"))


def assert_same(scores, ratio):
    sel = select_by_ratio(scores, ratio)
    keep, tau = sorted_selection(scores, ratio)
    np.testing.assert_array_equal(sel.keep, keep)
    assert sel.removed == int((~keep).sum()) == removal_count(len(keep), ratio)
    # τ the same float, to the bit (a -0.0 cut stays -0.0, a NaN cut stays NaN)
    assert np.array([sel.tau]).view(np.uint64)[0] == np.array([tau]).view(np.uint64)[0], (sel.tau, tau)


RATIOS = (0.0, 0.05, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 1.0)


@pytest.mark.parametrize("ratio", RATIOS)
def test_tie_heavy_cases(ratio):
    rng = np.random.default_rng(7)
    cases = [
        np.zeros(1000),                                   # every score tied
        rng.integers(0, 3, 1000).astype(float),            # three values
        rng.integers(0, 50, 10_001).astype(float),         # many ties at every cut
        np.repeat([2.0, 1.0, 0.0], [5, 500, 5]),           # the cut inside a long run
        np.where(rng.random(999) < 0.5, 0.0, -0.0),        # signed zeros compare equal
        np.concatenate([rng.random(100), [np.nan] * 50]),  # NaN sorts last
        np.array([np.nan] * 7),
        np.array([np.inf, -np.inf, np.inf, 0.0, -np.inf]),
        rng.random(1),
        np.array([]),
    ]
    for scores in cases:
        assert_same(scores, ratio)


def test_ties_go_by_index():
    sel = select_by_ratio(np.array([1.0, 0.5, 0.5, 0.5, 2.0]), 0.4)  # 2 of the three 0.5s: the first two
    assert sel.keep.tolist() == [True, False, False, True, True] and sel.tau == 0.5


@settings(max_examples=400, deadline=None)
@given(arrays(np.float64, st.integers(0, 300),
              elements=st.one_of(st.sampled_from([0.0, -0.0, 1.0, 2.5, np.inf, -np.inf, np.nan]),
                                 st.floats(allow_nan=True, allow_infinity=True))),
       st.floats(0.0, 1.0))
def test_equal_to_the_stable_sort(scores, ratio):
    assert_same(scores, ratio)


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 2000), st.integers(1, 6), st.floats(0.0, 1.0), st.integers(0, 2**32 - 1))
def test_keep_fractions_on_few_distinct_values(n, distinct, keep, seed):
    scores = np.random.default_rng(seed).integers(0, distinct, n).astype(np.float64)
    keep_mask, _ = sorted_selection(scores, ratios.from_keep(keep))
    np.testing.assert_array_equal(select_by_keep(scores, keep).keep, keep_mask)
