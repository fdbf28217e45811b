"""Paired per-view differences between two pruned sets and their 95 % interval.

The unit of comparison is a held-out view: two methods (or variants) pruned from the same scene at
the same ratio are rendered from the same cameras, so their PSNRs differ per view by the method
alone. For a candidate C and a reference R (e.g. ``random``) at one (scene, ratio)::

    d_v = PSNR_C(v) − PSNR_R(v)      for every view v measured for both,
    D   = mean_v d_v,   95 % CI by ``interval``:
          "t"          the house interval, D ± t_{0.975, n−1}·s/√n (:func:`harness.report.stats.t_ci`);
          "bootstrap"  the 2.5th / 97.5th percentiles of the means of 10,000 resamples of the views
                       with replacement (numpy default_rng(seed), seed 0) — the interval round one of
                       the reading selection was pre-registered with (``ctc_configs/study/reading.yaml``)

Views where either side reaches ``max_psnr`` (100 dB, +inf included: the pruned render equals the
reference render there, e.g. nothing pruned is visible) are excluded and counted (``n_excluded``).
The CI's half-width is (hi − lo)/2. Only rows with ``status == "ok"`` count. A side is chosen by
method and variant name, or by its parameters (``params`` JSON, compared as parsed mappings);
several reference variants (e.g. seeds) are averaged per view before differencing.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from typing import Any, Mapping, Sequence

import numpy as np
import pandas as pd

from harness.report import stats

RESAMPLES = stats.N_RESAMPLES
MAX_PSNR = stats.NEAR_IDENTICAL_DB


@dataclass(frozen=True)
class Paired:
    """A paired comparison: mean difference, its 95 % interval, views used/excluded."""

    mean: float
    lo: float
    hi: float
    n: int
    n_excluded: int

    @property
    def half_width(self) -> float:
        return (self.hi - self.lo) / 2.0

    def to_dict(self) -> dict:
        return {**asdict(self), "half_width": self.half_width}

    def text(self, digits: int = 2) -> str:
        if self.n == 0:
            return "n/a"
        return f"{self.mean:+.{digits}f} [{self.lo:+.{digits}f}, {self.hi:+.{digits}f}]"


INTERVALS = ("t", "bootstrap")


def bootstrap_ci(d: Sequence[float], *, resamples: int = RESAMPLES, seed: int = 0,
                 level: float = 0.95) -> tuple[float, float, float]:
    """(mean, lo, hi): the mean of ``d`` and its percentile-bootstrap CI
    (:func:`harness.report.stats.bootstrap_ci`, the one bootstrap of the house)."""
    return mean_interval(d, "bootstrap", resamples=resamples, seed=seed, level=level)


def mean_interval(d: Sequence[float], interval: str = stats.INTERVAL, *, resamples: int = RESAMPLES,
                  seed: int = 0, level: float = 0.95) -> tuple[float, float, float]:
    """(mean, lo, hi) of ``d`` with the named interval (module docstring)."""
    d = np.asarray(d, dtype=np.float64)
    if interval not in INTERVALS:
        raise ValueError(f"unknown interval {interval!r}; known: {', '.join(INTERVALS)}")
    if d.size == 0:
        return math.nan, math.nan, math.nan
    if interval == "t":
        lo, hi = stats.t_ci(d, confidence=level)
    else:
        lo, hi = stats.bootstrap_ci(d, n_resamples=resamples, confidence=level, seed=seed)
    return float(d.mean()), lo, hi


def _params_equal(text: str, want: Mapping[str, Any]) -> bool:
    try:
        have = json.loads(text) if text else {}
    except ValueError:
        return False
    return all(k in have and have[k] == v for k, v in want.items())


def per_view(df: pd.DataFrame, *, scene: str, method: str, ratio: float, variant: str | None = None,
             params: Mapping[str, Any] | None = None, metric: str = "psnr") -> pd.Series:
    """The metric per view (index: view name) of one (scene, method, variant or params, ratio)."""
    rows = df[(df["status"] == "ok") & (df["scene"] == scene) & (df["method"] == method)
              & ((df["ratio"] - ratio).abs() < 1e-9)]
    if variant is not None:
        rows = rows[rows["variant"] == variant]
    if params is not None:
        rows = rows[[_params_equal(p, params) for p in rows["params"]]]
    if rows.duplicated("view").any():
        raise ValueError(f"{scene} / {method}: several variants match; name one (variant or params)")
    return rows.set_index("view")[metric].astype(np.float64)


def paired_difference(candidate: pd.Series, reference: pd.Series | Sequence[pd.Series], *,
                      max_psnr: float = MAX_PSNR, resamples: int = RESAMPLES, seed: int = 0,
                      interval: str = stats.INTERVAL) -> Paired:
    """D = mean_v (candidate − reference) over the views both have, each side < ``max_psnr``
    (several references: averaged per view over the views all of them have)."""
    refs = [reference] if isinstance(reference, pd.Series) else list(reference)
    common = candidate.index
    for r in refs:
        common = common.intersection(r.index)
    ref = pd.concat([r.loc[common] for r in refs], axis=1)
    cand = candidate.loc[common]
    ok = (cand < max_psnr) & (ref < max_psnr).all(axis=1)
    d = (cand[ok] - ref[ok].mean(axis=1)).to_numpy()
    mean, lo, hi = mean_interval(d, interval, resamples=resamples, seed=seed)
    return Paired(mean, lo, hi, int(ok.sum()), int((~ok).sum()))


def compare(df: pd.DataFrame, *, scene: str, ratio: float, candidate: Mapping[str, Any],
            reference: Mapping[str, Any] | Sequence[Mapping[str, Any]], metric: str = "psnr",
            max_psnr: float = MAX_PSNR, resamples: int = RESAMPLES, seed: int = 0,
            interval: str = stats.INTERVAL) -> Paired:
    """:func:`paired_difference` of two sides each given as ``{method, variant?, params?}``."""
    def side(s):
        return per_view(df, scene=scene, ratio=ratio, metric=metric, **s)

    refs = [reference] if isinstance(reference, Mapping) else list(reference)
    return paired_difference(side(candidate), [side(r) for r in refs], max_psnr=max_psnr,
                             resamples=resamples, seed=seed, interval=interval)
