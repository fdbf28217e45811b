"""Adapter to the geometric back end (:mod:`.normals`, :mod:`.neighbors`, :mod:`.fpfh`).

Everything here works in voxel units (see :mod:`methods.betadesc.grid`), so radii are counted in
voxels. One hybrid search (the ``max_nn`` nearest voxel points strictly within ``radius``, the
point itself included — Open3D's FPFH neighbourhood) serves the FPFH and the descriptor
neighbourhood N(j) of :mod:`methods.betadesc.hsfh`.

Voxel normals: the principal eigenvector of the members' mean tensor ``T_j = mean_i n_i n_iᵀ`` of
the splat normals n_i (shortest scale axes, :func:`.normals.splat_normals`), with its largest-
magnitude component made positive, then oriented consistently by minimum-spanning-tree propagation
(:func:`.normals.orient_mst`, Hoppe et al., radius ``radius``, 10 neighbours). The tensor is summed
here with the grid's exact fixed-point sums rather than :func:`.normals.voxel_normals`' float sums
in splat order, so that a permutation of the splats leaves every normal — and every score —
bit-identical.
"""

from __future__ import annotations

import numpy as np

from methods.betadesc.fpfh import compute_fpfh
from methods.betadesc.grid import SplatGrid
from methods.betadesc.neighbors import Neighborhood, hybrid_search
from methods.betadesc.normals import orient_mst, splat_normals

_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def voxel_normals(grid: SplatGrid, quats: np.ndarray, scales_log: np.ndarray, radius: float) -> np.ndarray:
    """Consistently oriented unit normals (M, 3) of the voxel points (see the module doc)."""
    if grid.m == 0:
        return np.zeros((0, 3))
    n = splat_normals(quats, scales_log)
    mean = grid.voxel_mean(np.stack([n[:, a] * n[:, b] for a, b in _PAIRS], axis=1))
    tensor = np.empty((grid.m, 3, 3))
    for c, (a, b) in enumerate(_PAIRS):
        tensor[:, a, b] = tensor[:, b, a] = mean[:, c]
    normals = np.ascontiguousarray(np.linalg.eigh(tensor)[1][:, :, 2])
    big = normals[np.arange(grid.m), np.abs(normals).argmax(axis=1)]
    normals *= np.where(big < 0, -1.0, 1.0)[:, None]
    return orient_mst(grid.points, normals, radius)


def neighbourhood(points: np.ndarray, radius: float, max_nn: int) -> Neighborhood:
    """The hybrid (radius, max_nn) neighbourhood of every voxel point, itself included."""
    return hybrid_search(points, radius, max_nn)


def csr(nbh: Neighborhood) -> tuple[np.ndarray, np.ndarray]:
    """``(indptr, indices)`` of the padded neighbour lists."""
    valid = np.arange(nbh.index.shape[1])[None, :] < nbh.count[:, None]
    indptr = np.concatenate([[0], np.cumsum(nbh.count, dtype=np.int64)])
    return indptr, nbh.index[valid].astype(np.int64)


def fpfh(points: np.ndarray, normals: np.ndarray, nbh: Neighborhood) -> np.ndarray:
    """FPFH (M, 33) on the shared neighbourhood (equal to Open3D's for the same search)."""
    return compute_fpfh(points, normals, nbh.radius, nbh.max_nn, neighbors=nbh)
