"""Voxel downsampling of splat centres: the voxel cloud HSFH descriptors are computed on.

Voxel of a splat: ``key = floor((p − lo) / voxel)`` per axis, in float64, with ``lo`` the bounding-box
minimum of the centres — relative coordinates, so a scene translated by 1e6 gets the same voxels
(up to the float64 resolution of the translated coordinates themselves) and scaling the scene and the
voxel together changes nothing. Voxels are ordered by key (x, then y, then z); members of a voxel by
splat index. Keys are packed into one int64 (row-major cell index); voxel ids come from a dense
cell table when the bounding grid has at most max(8N, 2²⁰) cells (O(N + cells)), else from
``np.unique`` (O(N log N)); members are then grouped by a counting sort. Deterministic.

Voxel point = mean of the member centres, ``lo + Σ wᵢ(pᵢ − lo) / Σ wᵢ``: plain mean by default;
with ``weights`` (e.g. opacities) the weighted mean, falling back to the plain mean in a voxel
whose weights sum to 0 (an all-transparent voxel still has a position). Sums run over the members
in splat-index order, so a permutation of the splats can change a voxel point by float64 rounding
(~1e-16 relative) only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np


@dataclass(frozen=True)
class VoxelGrid:
    """Occupied voxels of a point set, with CSR membership.

    ``order[offsets[v]:offsets[v+1]]`` are the splats of voxel ``v`` (ascending);
    ``splat_to_voxel[i]`` is the voxel of splat ``i``; ``keys[v]`` its integer coordinates and
    ``points[v]`` its (weighted) mean centre. ``origin`` is the bounding-box minimum the keys are
    relative to: voxel v spans ``origin + keys[v]·voxel`` to ``origin + (keys[v]+1)·voxel``.
    """

    voxel: float
    origin: np.ndarray  # (3,) float64
    keys: np.ndarray  # (M, 3) int64
    points: np.ndarray  # (M, 3) float64
    order: np.ndarray  # (N,) int64
    offsets: np.ndarray  # (M+1,) int64
    splat_to_voxel: np.ndarray  # (N,) int64

    def __len__(self) -> int:
        return len(self.keys)

    @property
    def counts(self) -> np.ndarray:
        """Members per voxel (M,) int64."""
        return np.diff(self.offsets)

    def members(self, v: int) -> np.ndarray:
        """Splat indices of voxel ``v`` (ascending)."""
        return self.order[self.offsets[v] : self.offsets[v + 1]]


def as_points(points) -> np.ndarray:
    """``points`` as a contiguous float64 (N, 3) array; ValueError for another shape or NaN/inf."""
    p = np.ascontiguousarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points must be (N, 3), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("points contain NaN or inf")
    return p


def voxel_downsample(points: np.ndarray, voxel: float, weights: np.ndarray | None = None) -> VoxelGrid:
    """Group ``points`` (N, 3) into cubic voxels of edge ``voxel`` (see the module docstring)."""
    p = as_points(points)
    voxel = float(voxel)
    if not (np.isfinite(voxel) and voxel > 0.0):
        raise ValueError(f"voxel must be a positive finite size, got {voxel}")
    n = len(p)
    if weights is not None:
        w = np.asarray(weights, dtype=np.float64)
        if w.shape != (n,) or not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ValueError("weights must be (N,) finite and non-negative")
    if n == 0:
        z3 = np.zeros((0, 3))
        empty = np.zeros(0, np.int64)
        return VoxelGrid(voxel, np.zeros(3), z3.astype(np.int64), z3, empty, np.zeros(1, np.int64), empty)

    origin, top = _bbox(p)
    kmax = np.floor((top - origin) / voxel)
    if float(np.prod(kmax + 1.0)) >= 2.0**62:
        raise ValueError(f"voxel {voxel} is too small for a scene of extent {np.ptp(p, axis=0).max()}")
    dims = kmax.astype(np.int64) + 1
    lin = _packed_keys(p, origin, voxel, dims)
    ncell = int(np.prod(dims))
    if ncell <= max(8 * n, 1 << 20):
        s2v, m = _dense_ids(lin, ncell)
    else:
        uniq, s2v = np.unique(lin, return_inverse=True)
        s2v = s2v.astype(np.int64).reshape(-1)
        m = len(uniq)
    counts = np.bincount(s2v, minlength=m).astype(np.int64)
    offsets = np.zeros(m + 1, np.int64)
    np.cumsum(counts, out=offsets[1:])
    order = _counting_order(s2v, offsets)
    ulin = lin[order[offsets[:-1]]]
    keys = np.stack([ulin // (dims[1] * dims[2]), (ulin // dims[2]) % dims[1], ulin % dims[2]], axis=1)
    w = np.ones(n) if weights is None else w
    mean = _voxel_means(p, origin, s2v, w, m, weights is not None)
    return VoxelGrid(
        voxel=voxel,
        origin=origin,
        keys=keys,
        points=origin + mean,
        order=order,
        offsets=offsets,
        splat_to_voxel=s2v,
    )


@nb.njit(cache=True)
def _bbox(p):
    """(min, max) per axis of a (N, 3) array (numpy's axis-0 reduction is slow on this layout)."""
    lo = p[0].copy()
    hi = p[0].copy()
    for i in range(1, p.shape[0]):
        for a in range(3):
            lo[a] = min(lo[a], p[i, a])
            hi[a] = max(hi[a], p[i, a])
    return lo, hi


@nb.njit(cache=True, fastmath=False)
def _packed_keys(p, origin, voxel, dims):
    """Row-major cell index of ``floor((p − origin)/voxel)`` per point (x slowest, z fastest)."""
    n = p.shape[0]
    out = np.empty(n, np.int64)
    for i in range(n):
        k = 0
        for a in range(3):
            c = min(max(math.floor((p[i, a] - origin[a]) / voxel), 0), dims[a] - 1)
            k = k * dims[a] + c
        out[i] = k
    return out


@nb.njit(cache=True)
def _dense_ids(lin, ncell):
    """Voxel id of every point, ids numbered in increasing cell order, via a dense cell table."""
    table = np.zeros(ncell, np.int32)  # voxel ids < N < 2**31; half the memory of int64
    for c in lin:
        table[c] = 1
    m = 0
    for c in range(ncell):
        if table[c]:
            table[c] = m
            m += 1
    out = np.empty(len(lin), np.int64)
    for i in range(len(lin)):
        out[i] = table[lin[i]]
    return out, m


@nb.njit(cache=True)
def _counting_order(s2v, offsets):
    """Splat indices grouped by voxel, ascending within each voxel (counting sort)."""
    pos = offsets[:-1].copy()
    order = np.empty(len(s2v), np.int64)
    for i in range(len(s2v)):
        v = s2v[i]
        order[pos[v]] = i
        pos[v] += 1
    return order


@nb.njit(cache=True, fastmath=False)
def _voxel_means(p, origin, s2v, w, m, weighted):
    """Σ wᵢ(pᵢ − origin)/Σ wᵢ per voxel (plain mean where Σ wᵢ = 0 or unweighted), index order."""
    s = np.zeros((m, 3))
    sw = np.zeros((m, 3))
    cnt = np.zeros(m)
    wsum = np.zeros(m)
    for i in range(p.shape[0]):
        v = s2v[i]
        cnt[v] += 1.0
        wsum[v] += w[i]
        for a in range(3):
            r = p[i, a] - origin[a]
            s[v, a] += r
            sw[v, a] += w[i] * r
    out = np.empty((m, 3))
    for v in range(m):
        for a in range(3):
            out[v, a] = sw[v, a] / wsum[v] if weighted and wsum[v] > 0.0 else s[v, a] / cnt[v]
    return out
