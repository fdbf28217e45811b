"""Exact hybrid (radius + max_nn) neighbour search, the one open3d's FPFH uses, in numba.

open3d's ``KDTreeFlann::SearchHybrid(q, r, K)`` (nanoflann 1.5) runs a kNN query for the K nearest
points and keeps those with ``d² < r²`` (``std::lower_bound`` on r², so *strictly* inside), sorted by
``d²``. The query point itself is one of the points (``d² = 0``), so it takes one of the K slots and
FPFH skips slot 0. Squared distances are ``((q_x-p_x)² + (q_y-p_y)²) + (q_z-p_z)²`` in float64, the
order of nanoflann's ``L2_Adaptor``; we compute them the same way so the radius test and the
1/d² weights match bit for bit.

Our search: a dense uniform grid of cell size h ≈ r/2 (points sorted by cell, row-major, so a run of
cells along z is one contiguous slice; coordinates kept one array per axis). A query scans, per
(x, y) column, only the z-run of cells that can hold a point of its ball (bounds from its exact
position, widened by a slack of 1e-7·h plus 16 ulps of the largest coordinate, so rounding can only
widen them), keeping candidates with ``d² < ρ²``. ρ is first a guess — 1.3× the previous query's
k-th d² (queries run in cell order, so neighbours' densities are alike) — and if that ball holds
fewer than K points it is rescanned with a 3× larger d² bound, up to r; when ≥ K lie inside the
guess ball the K nearest are all inside it, so the guess changes the speed, never the result. Of
more than K candidates the K smallest under the total order ``(d², self first, index)`` are kept
(counting passes bracket the K-th d², quickselect inside the bracket). Ties at the K-th distance
are thus broken by point index (nanoflann breaks them by tree traversal order, so with exact ties
at the max_nn boundary the two searches can keep different points; that is the only way they
differ).

Output is padded ``(M, K)``: column 0 is the query itself, columns ``1..count-1`` its other
neighbours in an unspecified but deterministic order (not sorted by distance); memory is
``4·M·K`` bytes. Distances are not kept (``Neighborhood.squared_distances()`` recomputes them, and
FPFH recomputes each from the coordinates): on these VMs the first-touch page faults of a larger
output cost more than the three subtractions. Every query is independent (``prange`` over fixed
chunks of queries, no cross-thread reduction), so the result is bit-identical for any numba
thread count.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

_MAX_CELLS = 1 << 22  # dense grid size cap (32 MiB of int64 cell starts)
_GUESS_GROWTH = 1.3  # first-try ball: 1.3 × the previous query's k-th d²
_RETRY_GROWTH = 3.0  # a ball with too few points is retried with 3× the d² bound (at most r²)
_CHUNKS = 64  # queries are processed in this many independent chunks (any thread count)


@dataclass(frozen=True)
class Neighborhood:
    """Padded neighbour lists of ``points``: ``index[i, :count[i]]`` with ``index[i, 0] == i``."""

    points: np.ndarray  # (M, 3) float64, the searched points (not a copy)
    index: np.ndarray  # (M, K) int32, -1 past count
    count: np.ndarray  # (M,) int32, neighbours including the point itself (0 only if radius <= 0)
    radius: float
    max_nn: int

    def __len__(self) -> int:
        return len(self.count)

    def squared_distances(self) -> np.ndarray:
        """(M, K) squared distances in nanoflann's summation order, 0 past ``count``.

        Computed on each call, not stored (it would triple the search's output memory); kernels
        that need a distance recompute it from the coordinates in this same order, bit for bit.
        """
        valid = self.index >= 0
        j = np.where(valid, self.index, 0)
        e = self.points[:, None, :] - self.points[j]
        d2 = (e[..., 0] * e[..., 0] + e[..., 1] * e[..., 1]) + e[..., 2] * e[..., 2]
        return np.where(valid, d2, 0.0)


def _grid(points: np.ndarray, radius: float):
    """Dense grid of cell size h ≈ r/2: origin, h, dims (3,), point order by cell, cell starts.

    h grows if the grid would exceed ``_MAX_CELLS`` cells (a larger cell is still exact, only
    slower). Cells of the points are ``floor((p − lo)/h)`` clipped to the grid.
    """
    lo = points.min(axis=0)
    extent = points.max(axis=0) - lo
    h = 0.5 * radius
    while True:
        dims = np.floor(extent / h).astype(np.int64) + 1
        total = int(np.prod(dims.astype(np.float64)))
        if total <= _MAX_CELLS:
            break
        h *= max(1.01, (total / _MAX_CELLS) ** (1.0 / 3.0))
    order, starts = _bucket_by_cell(points, lo, h, dims)
    return lo, h, dims, order, starts


@nb.njit(cache=True)
def _bucket_by_cell(points, lo, h, dims):
    """Stable counting sort of the points by row-major cell: ``order`` and cell ``starts`` (C+1)."""
    m = points.shape[0]
    nx, ny, nz = dims[0], dims[1], dims[2]
    total = nx * ny * nz
    cell = np.empty(m, np.int64)
    starts = np.zeros(total + 1, np.int64)
    for i in range(m):
        cx = min(max(math.floor((points[i, 0] - lo[0]) / h), 0), nx - 1)
        cy = min(max(math.floor((points[i, 1] - lo[1]) / h), 0), ny - 1)
        cz = min(max(math.floor((points[i, 2] - lo[2]) / h), 0), nz - 1)
        cell[i] = (cx * ny + cy) * nz + cz
        starts[cell[i] + 1] += 1
    for c in range(total):  # starts[c + 1] = end of cell c
        starts[c + 1] += starts[c]
    order = np.empty(m, np.int64)
    for i in range(m - 1, -1, -1):  # back to front into each cell's end: stable
        starts[cell[i] + 1] -= 1
        order[starts[cell[i] + 1]] = i
    for c in range(total):  # now starts[c + 1] = start of cell c: shift down by one
        starts[c] = starts[c + 1]
    starts[total] = m
    return order, starts


@nb.njit(cache=True, inline="always")
def _cell_range(q, r, inv_h, slack, n):
    """Cells [a, b] of one axis whose slab can hold a point within r of coordinate q (grid units).

    Multiplying by 1/h instead of dividing by h moves the bounds by an ulp at most, far inside the
    slack (which only ever widens them)."""
    a = math.floor((q - r - slack) * inv_h)
    b = math.floor((q + r + slack) * inv_h)
    return max(a, 0), min(b, n - 1)


@nb.njit(cache=True, inline="always")
def _gap(q, cell, h, slack):
    """Distance from coordinate q to the slab [cell·h, (cell+1)·h), minus a rounding slack."""
    g = 0.0
    if q < cell * h:
        g = cell * h - q
    elif q >= (cell + 1) * h:
        g = q - (cell + 1) * h
    return max(g - slack, 0.0)


@nb.njit(cache=True, inline="always")
def _less(da, ra, db, rb):
    return da < db or (da == db and ra < rb)


@nb.njit(cache=True)
def _select_smallest(d2, rk, n, k):
    """Reorder ``d2[:n], rk[:n]`` in place so the k smallest (by (d2, rk)) come first."""
    lo = 0
    hi = n - 1
    t = k - 1
    while hi > lo:
        mid = (lo + hi) >> 1
        # median of three as pivot
        a, b, c = lo, mid, hi
        if _less(d2[b], rk[b], d2[a], rk[a]):
            a, b = b, a
        if _less(d2[c], rk[c], d2[b], rk[b]):
            b, c = c, b
            if _less(d2[b], rk[b], d2[a], rk[a]):
                a, b = b, a
        pd = d2[b]
        pr = rk[b]
        i = lo
        j = hi
        while i <= j:
            while _less(d2[i], rk[i], pd, pr):
                i += 1
            while _less(pd, pr, d2[j], rk[j]):
                j -= 1
            if i <= j:
                d2[i], d2[j] = d2[j], d2[i]
                rk[i], rk[j] = rk[j], rk[i]
                i += 1
                j -= 1
        if t <= j:
            hi = j
        elif t >= i:
            lo = i
        else:
            break


@nb.njit(cache=True, inline="always")
def _count_below(buf_d, n, v):
    """#{s < n : buf_d[s] < v} (a vectorised reduction)."""
    c = 0
    for s in range(n):
        c += buf_d[s] < v
    return c


@nb.njit(cache=True)
def _keep_smallest(buf_d, buf_r, n, k, hi, tmp_d, tmp_r):
    """Compact the k smallest of ``buf[:n]`` (by (d², rank); all d² < hi, n > k) to ``buf[:k]``.

    Brackets the k-th smallest value in ``[lo, hi)`` with ``#(d² < lo) < k ≤ #(d² < hi)`` by
    counting passes, alternating an interpolated cut (counts grow about linearly in d² for a
    surface) with bisection, until at most 8 candidates lie in the bracket or it cannot be split
    (ties). Then everything below ``lo`` is kept in scan order and quickselect picks the rest
    from the bracket only.
    """
    lo = 0.0
    c_lo = 0  # d² ≥ 0, so nothing is below 0
    c_hi = n
    for it in range(128):
        if c_hi - c_lo <= 8:
            break
        if it % 2 == 0:
            mid = lo + (hi - lo) * ((k - c_lo + 0.5) / (c_hi - c_lo))
        else:
            mid = 0.5 * (lo + hi)
        if not (lo < mid < hi):
            break
        c = _count_below(buf_d, n, mid)
        if c < k:
            lo = mid
            c_lo = c
        else:
            hi = mid
            c_hi = c
    o = 0
    t = 0
    for s in range(n):  # branch-free two-way compaction (in place: o ≤ s)
        d = buf_d[s]
        r = buf_r[s]
        buf_d[o] = d
        buf_r[o] = r
        o += d < lo
        tmp_d[t] = d
        tmp_r[t] = r
        t += (d >= lo) & (d < hi)
    need = k - o
    if t > need:
        _select_smallest(tmp_d, tmp_r, t, need)
    for s in range(need):
        buf_d[o + s] = tmp_d[s]
        buf_r[o + s] = tmp_r[s]
    return k


@nb.njit(cache=True, inline="always")
def _scan_ball(q, points, spx, spy, spz, order, lo, h, dims, starts, rr2, slack, buf_d, buf_r):
    """Append every point with d² < rr2 to ``buf`` (d², index); tight z-runs per (x, y) column."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    inv_h = 1.0 / h
    qx = points[q, 0]
    qy = points[q, 1]
    qz = points[q, 2]
    gx0 = qx - lo[0]  # grid-relative coordinates
    gy0 = qy - lo[1]
    gz0 = qz - lo[2]
    n = 0
    xa, xb = _cell_range(gx0, math.sqrt(rr2), inv_h, slack, nx)
    for x in range(xa, xb + 1):
        gx = _gap(gx0, x, h, slack)
        rx = rr2 - gx * gx
        if rx <= 0.0:
            continue
        ya, yb = _cell_range(gy0, math.sqrt(rx), inv_h, slack, ny)
        for y in range(ya, yb + 1):
            gy = _gap(gy0, y, h, slack)
            rxy = rx - gy * gy
            if rxy <= 0.0:
                continue
            za, zb = _cell_range(gz0, math.sqrt(rxy), inv_h, slack, nz)
            base = (x * ny + y) * nz
            # unsigned indices: numba then emits no negative-index wraparound per access (2× here)
            for s in range(nb.uint64(starts[base + za]), nb.uint64(starts[base + zb + 1])):
                ex = qx - spx[s]
                ey = qy - spy[s]
                ez = qz - spz[s]
                d = ex * ex + ey * ey + ez * ez
                # branch-free append (a good share of the candidates pass)
                buf_d[n] = d
                buf_r[n] = order[s]
                n += d < rr2
    return n


@nb.njit(cache=True)
def _finish_query(q, buf_d, buf_r, n, max_nn, rr2, tmp_d, tmp_r, out_idx, out_cnt):
    """Keep the max_nn nearest of the n candidates (all with d² < rr2), the query first, write
    row q; returns the kept k-th d² (``inf`` when fewer than max_nn were found)."""
    for s in range(n):
        if buf_r[s] == q:
            buf_r[s] = -1  # the query ranks before every other point at d² = 0
    if n > max_nn:
        n = _keep_smallest(buf_d, buf_r, n, max_nn, rr2, tmp_d, tmp_r)
    kth = 0.0
    for s in range(n):
        kth = max(kth, buf_d[s])
        if buf_r[s] == -1:  # the query itself to slot 0, as open3d's
            buf_d[s], buf_d[0] = buf_d[0], buf_d[s]
            buf_r[s], buf_r[0] = buf_r[0], buf_r[s]
    out_cnt[q] = n
    for s in range(n):
        out_idx[q, s] = q if buf_r[s] == -1 else buf_r[s]
    for s in range(n, max_nn):
        out_idx[q, s] = -1
    return kth if n == max_nn else math.inf


@nb.njit(parallel=True, cache=True, fastmath=False)
def _hybrid_kernel(points, lo, h, dims, order, starts, r2, max_nn, slack, out_idx, out_cnt):
    m = points.shape[0]
    # coordinates in cell order, one array per axis: a run of cells along z is one contiguous slice
    spx = np.empty(m)
    spy = np.empty(m)
    spz = np.empty(m)
    for s in range(m):
        spx[s] = points[order[s], 0]
        spy[s] = points[order[s], 1]
        spz[s] = points[order[s], 2]
    chunk = (m + _CHUNKS - 1) // _CHUNKS
    for ch in nb.prange(_CHUNKS):
        start = ch * chunk
        stop = min(m, start + chunk)
        if start >= stop:
            continue
        buf_d = np.empty(m, np.float64)
        buf_r = np.empty(m, np.int64)
        tmp_d = np.empty(m, np.float64)
        tmp_r = np.empty(m, np.int64)
        guess = r2
        for pos in range(start, stop):  # queries in cell order, so consecutive ones are close
            q = order[pos]
            # first a smaller ball from the previous query's k-th distance: if it already holds
            # max_nn points, the max_nn nearest are all inside it (exact); else grow it up to r.
            rr2 = min(r2, guess * _GUESS_GROWTH)
            n = _scan_ball(q, points, spx, spy, spz, order, lo, h, dims, starts, rr2, slack, buf_d, buf_r)
            while n < max_nn and rr2 < r2:
                rr2 = min(r2, max(rr2 * _RETRY_GROWTH, r2 / 64.0))  # ≤ 4 retries, even from 0
                n = _scan_ball(q, points, spx, spy, spz, order, lo, h, dims, starts, rr2, slack, buf_d, buf_r)
            kth = _finish_query(q, buf_d, buf_r, n, max_nn, rr2, tmp_d, tmp_r, out_idx, out_cnt)
            guess = kth if kth < math.inf else r2


def as_points(points) -> np.ndarray:
    """``points`` as a contiguous float64 (N, 3) array; ValueError for another shape or NaN/inf."""
    p = np.ascontiguousarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points must be (N, 3), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("points contain NaN or inf")
    return p


def hybrid_search(points: np.ndarray, radius: float, max_nn: int) -> Neighborhood:
    """For every point, its ``max_nn`` nearest points (itself included) with ``d² < radius²``.

    Same neighbour sets as open3d ``KDTreeSearchParamHybrid(radius, max_nn)`` except for exact
    distance ties at the max_nn boundary (see the module docstring).
    """
    pts = as_points(points)
    radius = float(radius)
    max_nn = int(max_nn)
    if not np.isfinite(radius) or radius <= 0.0 or max_nn < 1:
        raise ValueError(f"need radius > 0 and max_nn >= 1, got {radius}, {max_nn}")
    m = len(pts)
    idx = np.empty((m, max_nn), np.int32)  # every row is written, padding included
    cnt = np.empty(m, np.int32)
    if m:
        lo, h, dims, order, starts = _grid(pts, radius)
        # cell bounds are exact up to the rounding of (p − lo)/h: widen them by far more than that
        slack = 1e-7 * h + 16.0 * np.finfo(np.float64).eps * float(np.abs(pts).max())
        _hybrid_kernel(pts, lo, h, dims, order, starts, radius * radius, max_nn, slack, idx, cnt)
    return Neighborhood(points=pts, index=idx, count=cnt, radius=radius, max_nn=max_nn)
