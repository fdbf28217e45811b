"""Voxel statistics → every splat, by distance weighting (the paper's §4.1), and the weight w.

For splat i at ``t_i`` (voxel units) the candidate voxels are the occupied cells of the 2×2×2
block whose cell centres bracket it (the trilinear stencil, cells ``floor(t_i − ½) + {0,1}³``,
looked up in a per-voxel table of the 27 neighbours; the splat's own cell is always among them).
Each contributes with a Gaussian kernel of its distance to the voxel point ``v_k`` (member mean),
one voxel wide:

    K_ik = exp(−‖t_i − v_k‖² / 2),   x_i = Σ_k K_ik x_k / Σ_k K_ik,   w_i = min(1, Σ_k K_ik).

``w_i`` is the aggregation weight of Eq. 6: the kernel mass of descriptor support around the
splat. It is 1 inside populated regions and drops for a splat far from the voxel points around it
(an outlier in the corner of an isolated cell), whose neighbourhood evidence is then down-weighted;
its own voxel point is at most √3 voxels away, so w ≥ e^{−3/2} ≈ 0.22. A serial numba loop (deterministic for any
thread count).
"""

from __future__ import annotations

import numba
import numpy as np

from methods.betadesc.grid import SplatGrid, cell_keys


@numba.njit(cache=True)
def _interpolate(t, splat_voxel, cells, neighbour, points, values, out, weight, mode):
    """mode 0 gauss, 1 trilinear, 2 nearest; ``weight`` receives the raw kernel mass ΣK."""
    n = t.shape[0]
    c = values.shape[1]
    acc = np.empty(c)
    for i in range(n):
        j0 = splat_voxel[i]
        if mode == 2:
            for q in range(c):
                out[i, q] = values[j0, q]
            weight[i] = 1.0
            continue
        # stencil side per axis: cells floor(t − ½) + {0, 1} = own cell + {−1, 0} or {0, +1}
        s0 = 0 if t[i, 0] - cells[j0, 0] < 0.5 else 1
        s1 = 0 if t[i, 1] - cells[j0, 1] < 0.5 else 1
        s2 = 0 if t[i, 2] - cells[j0, 2] < 0.5 else 1
        acc[:] = 0.0
        ksum = 0.0
        for d0 in range(2):
            for d1 in range(2):
                for d2 in range(2):
                    # offsets −1..1 per axis, flattened as (o0+1)*9 + (o1+1)*3 + (o2+1)
                    slot = (s0 + d0) * 9 + (s1 + d1) * 3 + (s2 + d2)
                    j = neighbour[j0, slot]
                    if j < 0:
                        continue
                    if mode == 0:
                        r0 = t[i, 0] - points[j, 0]
                        r1 = t[i, 1] - points[j, 1]
                        r2 = t[i, 2] - points[j, 2]
                        kern = np.exp(-0.5 * (r0 * r0 + r1 * r1 + r2 * r2))
                    else:
                        kern = ((1.0 - abs(t[i, 0] - cells[j, 0] - 0.5))
                                * (1.0 - abs(t[i, 1] - cells[j, 1] - 0.5))
                                * (1.0 - abs(t[i, 2] - cells[j, 2] - 0.5)))
                    ksum += kern
                    for q in range(c):
                        acc[q] += kern * values[j, q]
        for q in range(c):
            out[i, q] = acc[q] / ksum
        weight[i] = ksum


def neighbour_table(grid: SplatGrid) -> tuple[np.ndarray, np.ndarray]:
    """Integer cells (M, 3) and, per occupied cell, the voxel index of its 27 neighbours
    (offsets −1..1 per axis, −1 where unoccupied or outside the grid), (M, 27)."""
    dims = grid.dims
    cells = np.stack([grid.keys // (dims[1] * dims[2]), (grid.keys // dims[2]) % dims[1],
                      grid.keys % dims[2]], axis=1)
    offsets = np.stack(np.meshgrid(*([np.arange(-1, 2)] * 3), indexing="ij"), axis=-1).reshape(27, 3)
    nb = cells[:, None, :] + offsets[None]
    inside = ((nb >= 0) & (nb < dims)).all(axis=2)
    key = cell_keys(np.where(inside[..., None], nb, 0), dims)
    j = np.minimum(np.searchsorted(grid.keys, key), grid.m - 1)
    found = inside & (grid.keys[j] == key)
    return cells, np.where(found, j, -1).astype(np.int64)


KERNELS = {"gauss": 0, "trilinear": 1, "nearest": 2}
W_MODES = ("clip-sum", "sum", "sum-median", "one")


def aggregation_weight(mass: np.ndarray, mode: str) -> np.ndarray:
    """w of Eq. 4 from the kernel mass ΣK per splat (see the module docstring)."""
    mass = np.asarray(mass, dtype=np.float64)
    if mode == "clip-sum":
        return np.minimum(1.0, mass)
    if mode == "sum":
        return mass.copy()
    if mode == "sum-median":
        return mass / np.median(mass) if mass.size else mass.copy()
    if mode == "one":
        return np.ones_like(mass)
    raise ValueError(f"unknown w_mode {mode!r}; known: {', '.join(W_MODES)}")


def interpolate_to_splats(grid: SplatGrid, values: np.ndarray, kernel: str = "gauss",
                          w_mode: str = "clip-sum") -> tuple[np.ndarray, np.ndarray]:
    """Per-splat values (N, C) and aggregation weights w (N,) from per-voxel ``values`` (M, C);
    the defaults are the v1 reading (Gaussian kernel, w = min(1, ΣK))."""
    if kernel not in KERNELS:
        raise ValueError(f"unknown kernel {kernel!r}; known: {', '.join(KERNELS)}")
    values = np.ascontiguousarray(values, dtype=np.float64)
    n = len(grid.t)
    out = np.zeros((n, values.shape[1]))
    mass = np.zeros(n)
    if n:
        cells, neighbour = neighbour_table(grid)
        _interpolate(np.ascontiguousarray(grid.t), grid.splat_voxel, cells, neighbour,
                     np.ascontiguousarray(grid.points), values, out, mass, KERNELS[kernel])
    return out, aggregation_weight(mass, w_mode)
