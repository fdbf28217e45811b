"""Shared ratio targeting: every method is compared at exactly the same splat count.

Removing a ratio r of N splats removes exactly ``k = round(r·N)`` splats (Python's round,
half to even), the k lowest scores, ties broken by index (the lower index is removed first),
i.e. a stable sort on (score, index). τ is reported as the largest removed score (the score
value at the cut); with k = 0 it is −inf. ``keep`` fractions are ``ratio = 1 − keep``
(:mod:`harness.core.ratios`).
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
    order = np.argsort(scores, kind="stable")
    keep = np.ones(n, dtype=bool)
    keep[order[:k]] = False
    tau = float(scores[order[k - 1]]) if k > 0 else float("-inf")
    return PruneSelection(keep=keep, removed=k, tau=tau, tau_quantile=k / n if n else 0.0)


def select_by_keep(scores: np.ndarray, keep_fraction: float) -> PruneSelection:
    return select_by_ratio(scores, ratios.from_keep(keep_fraction))
