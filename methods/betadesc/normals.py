"""Normals of the voxel cloud from the splats' shortest axes, consistently oriented.

Per splat the normal is the column of R (quaternion wxyz, normalised) belonging to the smallest scale
(``argmin scales_log``; the first axis wins an exact tie): a trained splat on a surface is a flat
disc whose thin axis is the surface normal. Its sign is meaningless.

Per voxel (the cells of :mod:`methods.betadesc.grid`), the sign-invariant aggregate is the
principal eigenvector of the members' mean tensor ``T = mean nᵢ nᵢᵀ`` (the axis best aligned with all
member normals, i.e. the minimiser of Σ (1 − (n·nᵢ)²)), its sign made canonical (largest-magnitude
component positive) so that the result does not depend on LAPACK's sign choice.

Orientation matters because FPFH is not sign invariant: flipping one normal of a pair changes
α, φ and θ, and flipping *all* normals mirrors the α and θ histograms. :func:`orient_mst` (Hoppe
et al. 1992, as open3d's ``orient_normals_consistent_tangent_plane``): on the graph of each point's
``ORIENT_NN`` nearest neighbours within the radius, a minimum spanning tree with edge cost
``2 − |nᵢ·nⱼ|`` (in [1, 2]: the +1 keeps zero costs out of scipy's sparse graph and does not change
which tree is minimal), traversed breadth first from one root per connected component; a child is
flipped when ``n_child·n_parent < 0``. Each root is the component's point farthest from the cloud
centroid, oriented away from the centroid — where the radial direction is most reliable.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import (
    breadth_first_order,
    connected_components,
    minimum_spanning_tree,
)

from methods.betadesc.grid import SplatGrid
from methods.betadesc.neighbors import hybrid_search

#: neighbours (besides the point itself) of the orientation graph
ORIENT_NN = 10


def splat_normals(rotations: np.ndarray, scales_log: np.ndarray) -> np.ndarray:
    """Unit normals (N, 3) float64: the shortest local axis of each splat, in world space.

    ``rotations`` is either (N, 3, 3) matrices whose columns are the local axes, or (N, 4)
    quaternions (w, x, y, z), normalised here (a zero quaternion is the identity, as in
    :func:`harness.core.scene.normalized_quats`).
    """
    s = np.ascontiguousarray(scales_log, dtype=np.float64)
    rot = np.ascontiguousarray(rotations, dtype=np.float64)
    n = len(s)
    if s.shape != (n, 3):
        raise ValueError(f"scales_log must be (N, 3), got {s.shape}")
    if rot.shape == (n, 3, 3):
        out = _matrix_axes(rot, s)
    elif rot.shape == (n, 4):
        out = _quat_axes(rot, s)
    else:
        raise ValueError(f"rotations must be ({n}, 3, 3) or ({n}, 4), got {rot.shape}")
    return out


@nb.njit(cache=True, inline="always")
def _shortest(s, i):
    a = 0
    if s[i, 1] < s[i, a]:
        a = 1
    if s[i, 2] < s[i, a]:
        a = 2
    return a


@nb.njit(cache=True, inline="always")
def _unit(out, i):
    norm = math.sqrt(out[i, 0] ** 2 + out[i, 1] ** 2 + out[i, 2] ** 2)
    if norm > 0.0:
        for a in range(3):
            out[i, a] /= norm


@nb.njit(cache=True, fastmath=False)
def _matrix_axes(rot, s):
    out = np.empty((rot.shape[0], 3))
    for i in range(rot.shape[0]):
        a = _shortest(s, i)
        for r in range(3):
            out[i, r] = rot[i, r, a]
        _unit(out, i)
    return out


@nb.njit(cache=True, fastmath=False)
def _quat_axes(quat, s):
    """Column ``argmin s`` of R(q) for unit (w, x, y, z), without building R (3DGS convention)."""
    out = np.empty((quat.shape[0], 3))
    for i in range(quat.shape[0]):
        w, x, y, z = quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3]
        qn = math.sqrt(w * w + x * x + y * y + z * z)
        if qn > 0.0:
            w, x, y, z = w / qn, x / qn, y / qn, z / qn
        else:
            w, x, y, z = 1.0, 0.0, 0.0, 0.0
        a = _shortest(s, i)
        if a == 0:
            out[i, 0] = 1 - 2 * (y * y + z * z)
            out[i, 1] = 2 * (x * y + w * z)
            out[i, 2] = 2 * (x * z - w * y)
        elif a == 1:
            out[i, 0] = 2 * (x * y - w * z)
            out[i, 1] = 1 - 2 * (x * x + z * z)
            out[i, 2] = 2 * (y * z + w * x)
        else:
            out[i, 0] = 2 * (x * z + w * y)
            out[i, 1] = 2 * (y * z - w * x)
            out[i, 2] = 1 - 2 * (x * x + y * y)
        _unit(out, i)
    return out


_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def voxel_normals(grid: SplatGrid, quats: np.ndarray, scales_log: np.ndarray, radius: float) -> np.ndarray:
    """Consistently oriented unit normals (M, 3) of the voxel points: the principal eigenvector of
    the members' mean tensor ``T_j = mean_i n_i n_iᵀ`` (summed with the grid's exact fixed-point sums,
    so a permutation of the splats leaves every normal bit-identical), canonical sign, then MST
    orientation with radius ``radius`` (voxels)."""
    if len(scales_log) != len(grid.t):
        raise ValueError(f"{len(scales_log)} splats for a grid of {len(grid.t)}")
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


def orient_mst(points: np.ndarray, normals: np.ndarray, radius: float, k: int = ORIENT_NN) -> np.ndarray:
    """Consistently oriented copy of ``normals`` by MST propagation (module docstring, ``"mst"``)."""
    p = np.asarray(points, dtype=np.float64)
    n = np.array(normals, dtype=np.float64)
    m = len(p)
    if m == 0:
        return n
    nbh = hybrid_search(p, radius, k + 1)
    rows = np.repeat(np.arange(m), nbh.count - 1)
    valid = np.arange(nbh.index.shape[1])[None, :] < nbh.count[:, None]
    valid[:, 0] = False  # the point itself
    cols = nbh.index[valid].astype(np.int64)
    cost = 2.0 - np.abs(np.einsum("ij,ij->i", n[rows], n[cols]))
    graph = coo_matrix((cost, (rows, cols)), shape=(m, m)).tocsr()
    tree = minimum_spanning_tree(graph)
    tree = (tree + tree.T).tocsr()
    ncomp, labels = connected_components(tree, directed=False)
    centre = p.mean(axis=0)
    far = np.einsum("ij,ij->i", p - centre, p - centre)
    by = np.lexsort((np.arange(m), -far, labels))  # per label: farthest first, then lowest index
    first = np.ones(m, bool)
    first[1:] = labels[by][1:] != labels[by][:-1]
    roots = by[first]
    # one traversal: a virtual node m linked to every root
    t = tree.tocoo()
    full = coo_matrix(
        (np.append(t.data, np.ones(ncomp)), (np.append(t.row, np.full(ncomp, m)), np.append(t.col, roots))),
        shape=(m + 1, m + 1),
    ).tocsr()
    seq, pred = breadth_first_order(full, m, directed=False, return_predecessors=True)
    _propagate(seq[1:].astype(np.int64), pred.astype(np.int64), n, p, centre, m)
    return n


@nb.njit(cache=True)
def _propagate(seq, pred, n, p, centre, root):
    """Flip normals in BFS order so each agrees with its parent; roots point away from centre."""
    for node in seq:
        par = pred[node]
        if par == root:
            d = 0.0
            for a in range(3):
                d += n[node, a] * (p[node, a] - centre[a])
        else:
            d = n[node, 0] * n[par, 0] + n[node, 1] * n[par, 1] + n[node, 2] * n[par, 2]
        if d < 0.0:
            for a in range(3):
                n[node, a] = -n[node, a]
