"""Adapter to the geometric back end: voxel normals, radius neighbourhoods, FPFH.

Everything here works in voxel units (see :mod:`methods.betadesc.grid`), so radii are counted in
voxels. The FPFH itself is Open3D's ``compute_fpfh_feature`` (hybrid search: the ``max_nn``
nearest voxel points within ``radius``).

Normals: each splat's shortest scale axis ``a_i`` (the column of R_i for its smallest scale) is
sign-ambiguous, so a voxel's normal is the principal eigenvector of the members' mean axis tensor
``T_j = mean_i a_i a_iᵀ`` (exact, order-independent sum). It is oriented consistently *outwards*:
``n_j · (v_j − c) ≥ 0`` with ``c`` the mean of the voxel points; exactly perpendicular normals get
their first non-zero component positive.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.spatial import cKDTree

from methods.betadesc.grid import SplatGrid


@numba.njit(cache=True)
def _shortest_axes(quats, scales_log, out):
    for i in range(quats.shape[0]):
        w, x, y, z = quats[i, 0], quats[i, 1], quats[i, 2], quats[i, 3]
        norm = np.sqrt(w * w + x * x + y * y + z * z)
        if norm > 0.0:
            w, x, y, z = w / norm, x / norm, y / norm, z / norm
        else:
            w, x, y, z = 1.0, 0.0, 0.0, 0.0
        k = 0
        if scales_log[i, 1] < scales_log[i, k]:
            k = 1
        if scales_log[i, 2] < scales_log[i, k]:
            k = 2
        if k == 0:
            out[i, 0], out[i, 1], out[i, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)
        elif k == 1:
            out[i, 0], out[i, 1], out[i, 2] = 2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)
        else:
            out[i, 0], out[i, 1], out[i, 2] = 2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)


def shortest_axes(quats: np.ndarray, scales_log: np.ndarray) -> np.ndarray:
    """Unit world-space direction of each splat's shortest scale axis (N, 3) float64: the column
    of R(q/‖q‖) for the smallest log-scale (first one on ties; zero quaternion → identity)."""
    out = np.empty((len(quats), 3))
    _shortest_axes(np.ascontiguousarray(quats, dtype=np.float64),
                   np.ascontiguousarray(scales_log, dtype=np.float64), out)
    return out


def voxel_normals(grid: SplatGrid, axes: np.ndarray) -> np.ndarray:
    """Consistently oriented unit normals (M, 3) from member shortest axes."""
    pairs = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
    prod = np.stack([axes[:, a] * axes[:, b] for a, b in pairs], axis=1)
    mean = grid.voxel_mean(prod)
    tensor = np.empty((grid.m, 3, 3))
    for c, (a, b) in enumerate(pairs):
        tensor[:, a, b] = tensor[:, b, a] = mean[:, c]
    _, vecs = np.linalg.eigh(tensor)
    normals = vecs[:, :, 2]
    side = np.einsum("ij,ij->i", normals, grid.points - grid.points.mean(axis=0))
    first = normals[np.arange(grid.m), np.argmax(normals != 0, axis=1)]
    flip = (side < 0) | ((side == 0) & (first < 0))
    normals[flip] *= -1.0
    return normals


def radius_neighbours(points: np.ndarray, radius: float, max_nn: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``max_nn`` nearest points within ``radius`` of every point (itself included), as CSR
    ``(indptr, indices)``; deterministic (single-threaded k-d tree)."""
    m = len(points)
    k = min(max_nn, m)
    dist, idx = cKDTree(points).query(points, k=k, distance_upper_bound=radius, workers=1)
    idx = idx.reshape(m, k)
    valid = np.isfinite(dist.reshape(m, k))
    indptr = np.concatenate([[0], np.cumsum(valid.sum(axis=1))]).astype(np.int64)
    return indptr, idx[valid].astype(np.int64)


def compute_fpfh(points: np.ndarray, normals: np.ndarray, radius: float, max_nn: int) -> np.ndarray:
    """FPFH (M, 33) float64 of points with normals (Open3D, hybrid radius/max_nn search)."""
    import open3d as o3d

    if len(points) == 0:
        return np.zeros((0, 33))
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(points)))
    cloud.normals = o3d.utility.Vector3dVector(np.ascontiguousarray(normals))
    feature = o3d.pipelines.registration.compute_fpfh_feature(
        cloud, o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=max_nn))
    return np.asarray(feature.data, dtype=np.float64).T.copy()
