"""Voxel grid of splat centres in *voxel units*, with exact, order-independent per-voxel sums.

Coordinates: ``t = (x − lo) / h`` (float64) with ``lo`` the bounding-box minimum and
``h = voxel · diag`` (a fraction of the bounding-box diagonal; ``h = 1`` if the diagonal is 0).
Working in voxel units makes every later radius and distance relative, so translating or scaling
the scene changes nothing but float rounding.

Splat i lies in cell ``floor(t_i)``; occupied cells are numbered in increasing order of their key
``(k_x·D_y + k_y)·D_z + k_z`` — a canonical order that does not depend on the order of the splats.

Exactness: every per-voxel sum is a sum of *integer-valued* float64 numbers (quantities in [-1, 1]
quantised to a fixed point of 2⁻²⁴ before summing). Such sums are exact below 2⁵³ (2²⁹ members),
so they do not depend on summation order: permuting the splats permutes nothing at
voxel level, and results are bit-identical for any thread count. This is the project's one voxel
grid: descriptors, normals (:func:`methods.betadesc.normals.voxel_normals`), interpolation and the
benchmarks all use it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

FIXED = float(2**24)  # fixed-point scale for exact sums of values in [-1, 1]


@numba.njit(cache=True)
def _fixed_sums(index, values, m):
    """out[index[i]] += rint(values[i] · 2²⁴), serially; integer-valued, hence exact."""
    out = np.zeros((m, values.shape[1]))
    for i in range(values.shape[0]):
        j = index[i]
        for c in range(values.shape[1]):
            out[j, c] += np.rint(values[i, c] * 16777216.0)
    return out


def fixed_sums(index: np.ndarray, values: np.ndarray, m: int) -> np.ndarray:
    """Exact per-group sums of ``values`` (N, C) in [-1, 1], in units of 2⁻²⁴ (integer float64)."""
    values = np.asarray(values, dtype=np.float64)
    flat = values.reshape(len(values), -1)
    return _fixed_sums(np.asarray(index, dtype=np.int64), np.ascontiguousarray(flat), m).reshape(
        (m,) + values.shape[1:])


@dataclass(frozen=True)
class SplatGrid:
    lo: np.ndarray          # (3,) world origin (bounding-box minimum)
    h: float                # voxel edge in world units
    dims: np.ndarray        # (3,) int64 cells per axis
    t: np.ndarray           # (N, 3) float64 splat centres in voxel units
    splat_voxel: np.ndarray  # (N,) int64 voxel index of every splat
    keys: np.ndarray        # (M,) int64 sorted keys of the occupied cells
    counts: np.ndarray      # (M,) float64 members per voxel
    points: np.ndarray      # (M, 3) float64 voxel points (member mean) in voxel units

    @property
    def m(self) -> int:
        return len(self.keys)

    def voxel_sum(self, values: np.ndarray) -> np.ndarray:
        """Exact per-voxel sums of per-splat values in [-1, 1], (N, …) -> (M, …), in units of 2⁻²⁴."""
        return fixed_sums(self.splat_voxel, values, self.m)

    def voxel_mean(self, values: np.ndarray) -> np.ndarray:
        """Mean over members of values in [-1, 1] (exact sums of the 2⁻²⁴-quantised values)."""
        sums = self.voxel_sum(values) / FIXED
        return sums / self.counts.reshape((-1,) + (1,) * (sums.ndim - 1))


def cell_keys(cells: np.ndarray, dims: np.ndarray) -> np.ndarray:
    """Linear keys of integer cells (…, 3) for a grid of ``dims`` cells (caller keeps them in range)."""
    return (cells[..., 0] * dims[1] + cells[..., 1]) * dims[2] + cells[..., 2]


def occupied_cells(key: np.ndarray, n_cells: int) -> tuple[np.ndarray, np.ndarray]:
    """Sorted distinct keys and each splat's index into them. A dense cell table (O(N + cells))
    when the grid is small, ``np.unique`` (a sort) otherwise; both give the same answer."""
    if n_cells <= max(4 * len(key), 1 << 20):
        occupied = np.bincount(key, minlength=n_cells) > 0
        keys = np.flatnonzero(occupied).astype(np.int64)
        table = np.cumsum(occupied) - 1
        return keys, table[key].astype(np.int64)
    keys, inverse = np.unique(key, return_inverse=True)
    return keys, inverse.astype(np.int64).reshape(-1)


def build_grid(means: np.ndarray, voxel: float) -> SplatGrid:
    """Voxelise splat centres with edge ``voxel × bounding-box diagonal``."""
    if not (np.isfinite(voxel) and voxel > 0):
        raise ValueError(f"voxel must be a positive fraction of the bounding-box diagonal, got {voxel}")
    x = np.asarray(means, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or len(x) == 0 or not np.all(np.isfinite(x)):
        raise ValueError(f"need a non-empty (N, 3) array of finite splat centres, got shape {x.shape}")
    lo = x.min(axis=0)
    hi = x.max(axis=0)
    diag = float(np.linalg.norm(hi - lo))
    h = voxel * diag if diag > 0 else 1.0
    t = (x - lo) / h
    cells = np.floor(t).astype(np.int64)
    dims = cells.max(axis=0) + 1
    if float(np.prod(dims.astype(np.float64))) > 2.0**62:
        raise ValueError(f"voxel {voxel} is too small for this scene ({dims.tolist()} cells)")
    key = cell_keys(cells, dims)
    keys, splat_voxel = occupied_cells(key, int(np.prod(dims)))
    counts = np.bincount(splat_voxel, minlength=len(keys)).astype(np.float64)
    offsets = fixed_sums(splat_voxel, t - cells, len(keys)) / FIXED / counts[:, None]  # in [0, 1)
    kz = keys % dims[2]
    ky = (keys // dims[2]) % dims[1]
    kx = keys // (dims[1] * dims[2])
    points = np.stack([kx, ky, kz], axis=1).astype(np.float64) + offsets
    return SplatGrid(lo=lo, h=h, dims=dims, t=t, splat_voxel=splat_voxel, keys=keys,
                     counts=counts, points=points)
