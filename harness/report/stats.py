"""The statistics behind every table cell: means over views, paired differences, their 95 % interval.

**The interval** (:func:`mean_ci`, described for captions by :data:`INTERVAL_DESCRIPTION`): the
Student-t interval of the mean of n paired differences d₁…dₙ,

    d̄ ± t_{0.975, n−1} · s / √n,     s² = Σ (dᵢ − d̄)² / (n − 1),

exact for normal differences at every n. A study measures ~8 held-out views per cell, and at n = 8
the *percentile bootstrap* the tables used before (:func:`bootstrap_ci`, still here: round one of the
reading selection was pre-registered with it) is too narrow: its resampled means have spread
s·√((n−1)/n)/√n and it uses normal rather than t quantiles (1.96 vs 2.36 at n = 8), so it covers the
true mean ~88 % of the time instead of 95 % (``harness bench intervals`` simulates both:
``results/bench/intervals.md``). The t interval needs no seed; with fewer than 2 values, or a value
that is not finite, there is no interval (NaN); n equal values give the zero-width interval at them.

**Bootstrap** (kept for round one and the coverage check). :func:`bootstrap_ci` is the 95 %
*percentile* bootstrap of the mean: 10,000 resamples (with replacement) of the n values, drawn with
``numpy.random.default_rng(0)`` — the same draws as ``scipy.stats.bootstrap((x,), np.mean,
method="percentile", rng=default_rng(0))`` — and the 2.5 / 97.5 % percentiles (linear interpolation)
of the resampled means.

**Paired differences.** A method is compared with a reference row (the same scene and ratio; which
row is the table's choice, see :mod:`harness.report.cells`) view by view: d = x(method, view) −
x(reference, view) over the (frame, view) pairs both were measured on, then the mean of d and the
interval of that mean — one interval on the difference, not two independent intervals.

**Near-identical views.** A measured view is *near-identical* when any of its dB metrics (a metric
registered with ``unit="dB"``: PSNR, and MPEG's RGB/YUV-PSNR with their OM variants) is at least
:data:`NEAR_IDENTICAL_DB` = 100 dB — that covers PSNR = +inf (identical renders) and MPEG's 999.99
cap. Such a view says "pruning changed (almost) nothing here" and its dB value is a huge number that
would dominate any mean, so dB means and dB differences exclude it (a pair is excluded when either
side is near-identical); every cell counts them (``n_near_identical``) and the tables mark the cell.
Bounded metrics (SSIM, LPIPS) keep every view. Medians are over every view (inf included).
Metrics against a captured photo (``gt_*``) neither flag nor drop a view: a pruned render equal
to the unpruned one is ~20 dB from the photo, an ordinary value (:func:`drops_near`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pandas as pd

NEAR_IDENTICAL_DB = 100.0
N_RESAMPLES = 10_000
CONFIDENCE = 0.95
SEED = 0
#: the name of the house interval (:func:`mean_ci`), as tidy tables and captions carry it
INTERVAL = "t"
#: one sentence for captions and table notes: what every Δ's bracket is (n is the cell's own)
INTERVAL_DESCRIPTION = ("95 % Student-t interval of the mean paired per-view difference "
                        "(mean ± t₀.₉₇₅,ₙ₋₁·s/√n over the n views both sides were measured on)")


def is_db(metric: str) -> bool:
    """Is ``metric`` a PSNR in dB (registered with ``unit="dB"``, :mod:`harness.metrics.registry`)?"""
    from harness.metrics.registry import is_db as registered_db

    return registered_db(metric)


def drops_near(metric: str) -> bool:
    """Are near-identical views left out of ``metric``'s means and differences (dB metrics
    comparing pruned and unpruned renders; not those against a photo)?"""
    from harness.metrics.registry import is_gt

    return is_db(metric) and not is_gt(metric)


def near_identical(df: pd.DataFrame, metrics) -> np.ndarray:
    """Per row: is any pruned-vs-unpruned dB metric among ``metrics`` ≥ :data:`NEAR_IDENTICAL_DB`
    (inf included)?"""
    flag = np.zeros(len(df), dtype=bool)
    for m in metrics:
        if drops_near(m) and m in df:
            v = pd.to_numeric(df[m], errors="coerce").to_numpy(dtype=np.float64)
            flag |= np.nan_to_num(v, nan=-np.inf) >= NEAR_IDENTICAL_DB
    return flag


@lru_cache(maxsize=64)
def _indices(n: int, n_resamples: int, seed: int) -> np.ndarray:
    idx = np.random.default_rng(seed).integers(0, n, (n_resamples, n))
    idx.setflags(write=False)
    return idx


def bootstrap_ci(x, *, n_resamples: int = N_RESAMPLES, confidence: float = CONFIDENCE,
                 seed: int = SEED) -> tuple[float, float]:
    """Percentile bootstrap CI of the mean of ``x`` (module docstring); (nan, nan) below 2 values or
    when a value is not finite."""
    x = np.asarray(x, dtype=np.float64)
    if x.size < 2 or not np.all(np.isfinite(x)):
        return np.nan, np.nan
    if np.all(x == x[0]):
        return float(x[0]), float(x[0])
    means = x[_indices(x.size, n_resamples, seed)].mean(axis=1)
    alpha = (1.0 - confidence) / 2.0
    lo, hi = np.percentile(means, [100.0 * alpha, 100.0 * (1.0 - alpha)])
    return float(lo), float(hi)


def t_ci(x, *, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Student-t interval of the mean of ``x`` (module docstring); (nan, nan) below 2 values or
    when a value is not finite."""
    x = np.asarray(x, dtype=np.float64)
    if x.size < 2 or not np.all(np.isfinite(x)):
        return np.nan, np.nan
    mean = float(x.mean())
    if np.all(x == x[0]):
        return float(x[0]), float(x[0])
    half = t_quantile(0.5 + confidence / 2.0, x.size - 1) * x.std(ddof=1) / np.sqrt(x.size)
    return mean - float(half), mean + float(half)


@lru_cache(maxsize=None)
def t_quantile(p: float, dof: int) -> float:
    """Student-t quantile ``t_{p, dof}``: ``scipy.special.stdtrit``, the function ``scipy.stats.t.ppf``
    calls (the same bits), without importing scipy.stats (a second of every table build)."""
    from scipy.special import stdtrit

    return float(stdtrit(dof, p))


def mean_ci(x, *, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """The house 95 % interval of the mean (:data:`INTERVAL`: :func:`t_ci`); every table uses it."""
    return t_ci(x, confidence=confidence)


def n_text(n_pairs) -> str:
    """"n = 8" or "n = 6–8": the paired views behind the intervals of a table (NaN/0 ignored)."""
    n = pd.to_numeric(pd.Series(list(n_pairs), dtype=object), errors="coerce").dropna()
    n = n[n > 0].astype(int)
    if n.empty:
        return "n = 0"
    return f"n = {n.min()}" if n.min() == n.max() else f"n = {n.min()}–{n.max()}"


def interval_note(n_pairs) -> str:
    """What a table's brackets are, with its n: one line for table notes."""
    return f"[…]: {INTERVAL_DESCRIPTION}; {n_text(n_pairs)} paired views per interval"


def summary(values, near, metric: str) -> dict:
    """Mean and sample standard deviation (ddof = 1, as ns-eval's ``psnr_std``; NaN below 2 values)
    over the same views (dB metrics: those that are not near-identical), median (all views), counts."""
    v = np.asarray(values, dtype=np.float64)
    near = np.asarray(near, dtype=bool)
    ok = ~np.isnan(v)
    v, near = v[ok], near[ok]
    used = v[~near] if drops_near(metric) else v
    used = used[np.isfinite(used)]
    return {"mean": float(used.mean()) if used.size else np.nan,
            "std": float(used.std(ddof=1)) if used.size > 1 else np.nan,
            "median": float(np.median(v)) if v.size else np.nan,
            "n": int(v.size), "n_near_identical": int(near.sum())}


def paired_diffs(cur: pd.DataFrame, ref: pd.DataFrame, metric: str, keys=("frame", "view")) -> tuple[np.ndarray, int]:
    """Per-view differences cur − ref of ``metric`` over the views both have (matched on ``keys``)
    and the number of pairs left out as near-identical (dB metrics). ``cur`` and ``ref`` carry a
    boolean ``near`` column (:func:`near_identical`).

    The pairs are those of an inner join on ``keys`` in ``cur``'s row order (a key repeated in
    ``ref`` pairs with each of its rows, in ``ref``'s order), built with a dict: a table has
    thousands of cells of a few views each, where a DataFrame merge per cell cost most of a rerun."""
    return paired_diffs_at(columns(cur, metric), columns(ref, metric), metric, pair_index(cur, ref, keys))


def columns(frame: pd.DataFrame, metric: str) -> tuple[np.ndarray, np.ndarray]:
    """(values of ``metric`` as float64, the boolean ``near`` column) of a cell's rows."""
    return (pd.to_numeric(frame[metric], errors="coerce").to_numpy(dtype=np.float64),
            frame["near"].to_numpy(dtype=bool))


def pair_index(cur: pd.DataFrame, ref: pd.DataFrame, keys=("frame", "view")) -> tuple[np.ndarray, np.ndarray]:
    """Row positions (in ``cur``, in ``ref``) of the pairs :func:`paired_diffs` takes, computed once
    for every metric of a cell."""
    keys = [k for k in keys if k in cur and k in ref]

    def key_rows(df):  # NaN keys match each other, as in a merge
        return zip(*([None if isinstance(x, float) and x != x else x for x in df[c].tolist()] for c in keys))

    rows: dict = {}
    for j, k in enumerate(key_rows(ref)):
        rows.setdefault(k, []).append(j)
    pairs = [(i, j) for i, k in enumerate(key_rows(cur)) for j in rows.get(k, ())]
    if not pairs:
        return np.empty(0, np.intp), np.empty(0, np.intp)
    ci, ri = np.array(pairs, dtype=np.intp).T
    return ci, ri


def paired_diffs_at(cur, ref, metric: str, index) -> tuple[np.ndarray, int]:
    """:func:`paired_diffs` on the pairs ``index`` (:func:`pair_index`); ``cur``, ``ref``: each
    side's (values, near) arrays (:func:`columns`)."""
    ci, ri = index
    if not len(ci):
        return np.empty(0, np.float64), 0
    (cv, cn), (rv, rn) = cur, ref
    d = cv[ci] - rv[ri]
    excluded = (cn[ci] | rn[ri]) if drops_near(metric) else np.zeros(len(ci), bool)
    return d[~excluded & np.isfinite(d)].astype(np.float64), int(excluded.sum())


def paired(cur: pd.DataFrame, ref: pd.DataFrame, metric: str, keys=("frame", "view")) -> dict:
    """Mean paired difference (:func:`paired_diffs`), its interval (:func:`mean_ci`), the number of
    pairs used and of pairs left out as near-identical."""
    d, excluded = paired_diffs(cur, ref, metric, keys)
    lo, hi = mean_ci(d)
    return {"delta": float(d.mean()) if d.size else np.nan, "ci_low": lo, "ci_high": hi,
            "delta_median": float(np.median(d)) if d.size else np.nan,
            "n_pairs": int(d.size), "n_pairs_excluded": excluded}


def verdict(ci_low: float, ci_high: float, higher_is_better: bool) -> str:
    """``better`` / ``worse`` when the 95 % CI of the difference excludes 0, else ``unclear``."""
    if not (np.isfinite(ci_low) and np.isfinite(ci_high)):
        return "unclear"
    if ci_low > 0 or ci_high < 0:
        up = ci_low > 0
        return "better" if up == higher_is_better else "worse"
    return "unclear"
