"""Codebooks of the SOG writer: 256-entry scalar codebooks and the k-means SH palette.

**Scalar codebook** (:func:`codebook_1d`; scales, colours, SH palette values), PlayCanvas
splat-transform's ``quantize1dColumns`` (``src/lib/spatial/quantize-1d-core.ts``, v3.2.0, read and
restated): the values of every column are pooled and sorted; they fall into ``H = min(1024, n)``
histogram bins placed by a blend of rank and value,

    bin(v_i) = floor(H·(β·i/n + (1 − β)·(v_i − v_min)/(v_max − v_min))),
    β = clamp(1 − IQR/(v_max − v_min), ½, 0.999),

so heavy tails keep bins of their own; bin ``b`` holds ``c_b`` values of mean ``x_b`` and weighs
``w_b = c_b^½`` (sparse tails count for more than their share). Dynamic programming over the
non-empty bins in order then finds the split into ``K = min(256, non-empty bins)`` runs that
minimises ``Σ_runs Σ_b w_b·(x_b − x̄_run)²`` (exact: every split point is tried, ``O(K·H²)``);
the codebook is the runs' weighted means, ascending, padded to 256 with the last one. Each value is
coded by its nearest entry (ties to the upper one). At most 256 distinct values (a small SH
palette, values already quantised): the codebook is those values, so nothing is merged — where
splat-transform's ``min(1024, n)`` bins can put two of them in one bin.

**SH palette** (:func:`kmeans_palette`): scikit-learn's ``KMeans`` (Lloyd) on the splats' SH
coefficient vectors, ``init="random"`` (``k`` distinct splats, as splat-transform seeds it),
``n_init=1``, ``max_iter`` = the writer's iterations, ``tol=0``, a fixed ``random_state``. It runs on
one thread (threadpoolctl): its multi-threaded centroid update adds per-thread partial sums in the
order the threads finish, so the result would depend on scheduling; one thread gives the same bytes
for the same input on every run. Fewer splats than clusters: every splat is its own centroid.
Centroids no splat is labelled with are dropped and the labels renumbered in centroid order:
with fewer distinct vectors than clusters, scikit-learn leaves the surplus (empty) clusters at
arbitrary values far outside the data, which would otherwise stretch the palette's codebook. Each
kept entry is then the float64 mean of the points labelled with it (one last update step; the
float32 sums of the fit move an entry whose points are all equal by a few float32 steps).
"""

from __future__ import annotations

import numpy as np

from harness.core.errors import InputError

CODEBOOK_SIZE = 256
_MAX_BINS = 1024
_ALPHA = 0.5


def _histogram(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(bin means, bin weights) of the non-empty bins, in value order (module docstring)."""
    s = np.sort(values.astype(np.float64))
    n, lo, span = len(s), s[0], s[-1] - s[0]
    bins = min(_MAX_BINS, n)
    iqr = s[int(n * 0.75)] - s[int(n * 0.25)]
    beta = min(0.999, max(0.5, 1.0 - iqr / span))
    pos = beta * (np.arange(n) / n) + (1.0 - beta) * (s - lo) / span
    index = np.minimum(bins - 1, np.floor(bins * pos).astype(np.int64))
    counts = np.bincount(index, minlength=bins)
    sums = np.bincount(index, weights=s, minlength=bins)
    full = counts > 0
    return sums[full] / counts[full], counts[full].astype(np.float64) ** _ALPHA


def _optimal_runs(x: np.ndarray, w: np.ndarray, k: int) -> np.ndarray:
    """Weighted means of the ``k`` consecutive runs of ``x`` minimising the weighted squared error."""
    h = len(x)
    pw, pwx, pwxx = (np.concatenate([[0.0], np.cumsum(v)]) for v in (w, w * x, w * x * x))
    a, b = np.arange(h)[:, None] + 1, np.arange(h)[None, :]  # cost[s, j]: run s+1 .. j
    with np.errstate(invalid="ignore", divide="ignore"):
        ww = pw[b + 1] - pw[a]
        cost = (pwxx[b + 1] - pwxx[a]) - (pwx[b + 1] - pwx[a]) ** 2 / ww
    cost = np.where(a <= b, np.maximum(cost, 0.0), np.inf)
    best = pwxx[1:] - pwx[1:] ** 2 / pw[1:]  # one run: bins 0 .. j
    splits = []
    for _ in range(1, k):
        total = best[:, None] + cost
        split = np.argmin(total, axis=0)
        best = total[split, np.arange(h)]
        splits.append(split)
    ends, j = [h - 1], h - 1
    for split in reversed(splits):
        j = int(split[j])
        ends.append(j)
    ends = ends[::-1]
    starts = [0] + [e + 1 for e in ends[:-1]]
    return np.array([(pwx[e + 1] - pwx[s]) / (pw[e + 1] - pw[s]) for s, e in zip(starts, ends)])


def codebook_1d(columns: np.ndarray, source="scene") -> tuple[np.ndarray, np.ndarray]:
    """(256-entry float32 codebook, uint8 codes shaped like ``columns``) of finite values."""
    values = np.asarray(columns, np.float32)
    flat = values.ravel()
    if flat.size and not np.isfinite(flat).all():
        raise InputError(source, "a codebook value is not finite; SOG cannot store NaN or infinity")
    if flat.size == 0 or flat.max() - flat.min() < 1e-20:
        fill = float(flat[0]) if flat.size else 0.0
        return np.full(CODEBOOK_SIZE, fill, np.float32), np.zeros(values.shape, np.uint8)
    distinct = np.unique(flat)
    if len(distinct) <= CODEBOOK_SIZE:
        means = distinct
    else:
        x, w = _histogram(flat)
        means = np.sort(_optimal_runs(x, w, min(CODEBOOK_SIZE, len(x)))).astype(np.float32)
    book = np.concatenate([means, np.full(CODEBOOK_SIZE - len(means), means[-1], np.float32)])
    middles = (book[:-1].astype(np.float64) + book[1:]) * 0.5
    codes = np.searchsorted(middles, flat.astype(np.float64), side="right")
    return book, codes.astype(np.uint8).reshape(values.shape)


def kmeans_palette(points: np.ndarray, k: int, iterations: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(centroids (k', D) float32, labels (N,) int64) of the ``N`` points (module docstring)."""
    points = np.ascontiguousarray(points, np.float32)
    if len(points) <= k:
        return points.copy(), np.arange(len(points), dtype=np.int64)
    import warnings

    from sklearn.cluster import KMeans
    from sklearn.exceptions import ConvergenceWarning
    from threadpoolctl import threadpool_limits

    model = KMeans(n_clusters=k, init="random", n_init=1, max_iter=iterations, tol=0.0, random_state=seed,
                   algorithm="lloyd")
    with threadpool_limits(limits=1), warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)  # fewer distinct vectors than clusters
        model.fit(points)
    used = np.unique(model.labels_)
    labels = np.searchsorted(used, model.labels_).astype(np.int64)
    counts = np.bincount(labels, minlength=len(used)).astype(np.float64)
    means = np.stack([np.bincount(labels, weights=points[:, d], minlength=len(used)) for d in range(points.shape[1])],
                     axis=1) / counts[:, None]
    return means.astype(np.float32), labels
