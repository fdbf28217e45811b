"""Shared ratio targeting: every method is compared at exactly the same splat count.

Removing a ratio r of N splats removes exactly ``k = round(r·N)`` splats (Python's round,
half to even), the k lowest scores, ties broken by index (the lower index is removed first),
i.e. a stable sort on (score, index). τ is reported as the largest removed score (the score
value at the cut); with k = 0 it is −inf. ``keep`` fractions are ``ratio = 1 − keep``
(:mod:`harness.core.ratios`).

The selection is O(N), without sorting: τ is the k-th smallest score (``np.partition``); every
score below τ is removed, and of the scores equal to τ the lowest-indexed ``k − #{s < τ}`` — exactly
the first k of the stable order. NaN scores sort last, as in ``np.argsort`` (τ is NaN only when
fewer than k scores are numbers). τ is read from the last removed splat itself, so even its sign
of zero is that of the sorted selection.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.core import ratios


@dataclass(frozen=True)
class PruneSelection:
    keep: np.ndarray  # bool (N,), True = kept
    removed: int
    tau: float
    tau_quantile: float  # k / N: the score quantile used as the threshold

    @property
    def kept(self) -> int:
        return int(self.keep.sum())


def removal_count(n: int, ratio: float) -> int:
    if not 0.0 <= ratio <= 1.0:
        raise ValueError(f"pruning ratio must be in [0, 1], got {ratio}")
    return int(round(ratio * n))  # a canonical ratio (harness.core.ratios) times N


def select_by_ratio(scores: np.ndarray, ratio: float) -> PruneSelection:
    """Keep mask removing the ``round(ratio·N)`` lowest scores (ties: lower index first)."""
    scores = np.asarray(scores, dtype=np.float64)
    n = len(scores)
    k = removal_count(n, ratio)
    keep = np.ones(n, dtype=bool)
    if k == 0:
        return PruneSelection(keep=keep, removed=0, tau=float("-inf"), tau_quantile=0.0)
    cut = np.partition(scores, k - 1)[k - 1]  # the k-th smallest (NaN last, as argsort)
    if np.isnan(cut):
        below, at = ~np.isnan(scores), np.isnan(scores)
    else:
        below, at = scores < cut, scores == cut
    ties = np.flatnonzero(at)[: k - int(np.count_nonzero(below))]  # the lowest-indexed of the scores at the cut
    keep[below] = False
    keep[ties] = False
    return PruneSelection(keep=keep, removed=k, tau=float(scores[ties[-1]]), tau_quantile=k / n)


def select_by_keep(scores: np.ndarray, keep_fraction: float) -> PruneSelection:
    return select_by_ratio(scores, ratios.from_keep(keep_fraction))
