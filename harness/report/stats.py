"""The statistics behind every table cell: means over views, paired differences, bootstrap CIs.

**Bootstrap.** :func:`bootstrap_ci` is the 95 % *percentile* bootstrap of the mean: 10,000
resamples (with replacement) of the n values, drawn with ``numpy.random.default_rng(0)`` — the same
draws as ``scipy.stats.bootstrap((x,), np.mean, method="percentile", rng=default_rng(0))`` — and the
2.5 / 97.5 % percentiles (linear interpolation) of the resampled means. The seed is fixed, so a
table is the same every time it is rebuilt. With fewer than 2 values there is no interval (NaN).

**Paired differences.** A method is compared with a reference row (the same scene and ratio; which
row is the table's choice, see :mod:`harness.report.cells`) view by view: d = x(method, view) −
x(reference, view) over the (frame, view) pairs both were measured on, then the mean of d and the
bootstrap CI of that mean — one interval on the difference, not two independent intervals.

**Near-identical views.** A measured view is *near-identical* when any of its dB metrics (a metric
whose name contains ``psnr``: PSNR, and MPEG's RGB/YUV-PSNR with their OM variants) is at least
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


def is_db(metric: str) -> bool:
    """Is ``metric`` a PSNR in dB (its near-identical views are excluded from means)?"""
    return "psnr" in metric.lower()


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


def summary(values, near, metric: str) -> dict:
    """Mean (dB metrics: over views that are not near-identical), median (all views), counts."""
    v = np.asarray(values, dtype=np.float64)
    near = np.asarray(near, dtype=bool)
    ok = ~np.isnan(v)
    v, near = v[ok], near[ok]
    used = v[~near] if drops_near(metric) else v
    used = used[np.isfinite(used)]
    return {"mean": float(used.mean()) if used.size else np.nan,
            "median": float(np.median(v)) if v.size else np.nan,
            "n": int(v.size), "n_near_identical": int(near.sum())}


def paired_diffs(cur: pd.DataFrame, ref: pd.DataFrame, metric: str, keys=("frame", "view")) -> tuple[np.ndarray, int]:
    """Per-view differences cur − ref of ``metric`` over the views both have (matched on ``keys``)
    and the number of pairs left out as near-identical (dB metrics). ``cur`` and ``ref`` carry a
    boolean ``near`` column (:func:`near_identical`).

    The pairs are those of an inner join on ``keys`` in ``cur``'s row order (a key repeated in
    ``ref`` pairs with each of its rows, in ``ref``'s order), built with a dict: a table has
    thousands of cells of a few views each, where a DataFrame merge per cell cost most of a rerun."""
    keys = [k for k in keys if k in cur and k in ref]
    cv = pd.to_numeric(cur[metric], errors="coerce").to_numpy(dtype=np.float64)
    rv = pd.to_numeric(ref[metric], errors="coerce").to_numpy(dtype=np.float64)
    cn, rn = cur["near"].to_numpy(dtype=bool), ref["near"].to_numpy(dtype=bool)
    def key_rows(df):  # NaN keys match each other, as in a merge
        return zip(*([None if isinstance(x, float) and x != x else x for x in df[c].tolist()] for c in keys))

    rows: dict = {}
    for j, k in enumerate(key_rows(ref)):
        rows.setdefault(k, []).append(j)
    pairs = [(i, j) for i, k in enumerate(key_rows(cur)) for j in rows.get(k, ())]
    if not pairs:
        return np.empty(0, np.float64), 0
    ci, ri = np.array(pairs, dtype=np.intp).T
    d = cv[ci] - rv[ri]
    excluded = (cn[ci] | rn[ri]) if drops_near(metric) else np.zeros(len(ci), bool)
    return d[~excluded & np.isfinite(d)].astype(np.float64), int(excluded.sum())


def paired(cur: pd.DataFrame, ref: pd.DataFrame, metric: str, keys=("frame", "view")) -> dict:
    """Mean paired difference (:func:`paired_diffs`), its bootstrap CI, the number of pairs used and
    of pairs left out as near-identical."""
    d, excluded = paired_diffs(cur, ref, metric, keys)
    lo, hi = bootstrap_ci(d)
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
