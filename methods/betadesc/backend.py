"""Adapter to the geometric back end (:mod:`.neighbors`, :mod:`.fpfh`).

Everything here works in voxel units (see :mod:`methods.betadesc.grid`), so radii are counted in
voxels. One hybrid search (the ``max_nn`` nearest voxel points strictly within ``radius``, the
point itself included — Open3D's FPFH neighbourhood) serves the FPFH and the descriptor
neighbourhood N(j) of :mod:`methods.betadesc.hsfh`.

Voxel normals: :func:`methods.betadesc.normals.voxel_normals`.
"""

from __future__ import annotations

import numpy as np

from methods.betadesc.fpfh import compute_fpfh
from methods.betadesc.neighbors import Neighborhood, hybrid_search


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
