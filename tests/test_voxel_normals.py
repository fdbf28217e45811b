"""Voxel grid (CSR, means, invariances) and voxel normals (shortest axis, aggregation, orientation)."""

from __future__ import annotations

import numpy as np
import pytest

from harness.core.scene import quat_to_rotmat
from methods.betadesc.normals import orient_mst, splat_normals, voxel_normals
from methods.betadesc.voxel import voxel_downsample


def _brute_grid(points, voxel, weights=None):
    """Reference by dictionaries: key -> sorted members, weighted mean."""
    lo = points.min(axis=0)
    groups = {}
    for i, p in enumerate(points):
        groups.setdefault(tuple(np.floor((p - lo) / voxel).astype(np.int64)), []).append(i)
    keys = sorted(groups)
    means = []
    for k in keys:
        idx = np.array(groups[k])
        w = np.ones(len(idx)) if weights is None else weights[idx]
        if w.sum() <= 0:
            w = np.ones(len(idx))
        means.append(lo + (w[:, None] * (points[idx] - lo)).sum(axis=0) / w.sum())
    return keys, [groups[k] for k in keys], np.array(means)


@pytest.mark.parametrize("weighted", [False, True])
def test_voxel_csr_matches_brute_force(weighted):
    rng = np.random.default_rng(0)
    points = rng.normal(size=(3000, 3)) * [1.0, 0.5, 2.0]
    points[100:150] = points[:50]  # duplicates
    weights = rng.uniform(0, 1, 3000) if weighted else None
    if weighted:
        weights[points[:, 0] > 1.5] = 0.0  # all-transparent voxels fall back to the plain mean
    grid = voxel_downsample(points, 0.37, weights)
    keys, members, means = _brute_grid(points, 0.37, weights)
    assert [tuple(k) for k in grid.keys] == keys
    assert [grid.members(v).tolist() for v in range(len(grid))] == members
    assert np.allclose(grid.points, means, rtol=0, atol=1e-12)
    assert grid.offsets[0] == 0 and grid.offsets[-1] == len(points)
    assert np.array_equal(grid.counts, [len(m) for m in members])
    for v, mem in enumerate(members):
        assert np.all(grid.splat_to_voxel[mem] == v)


def test_voxel_grid_far_from_origin_and_scaled():
    """Multiples of 2⁻²⁰ below 16: adding 1e6 is exact, so the grid must be identical."""
    rng = np.random.default_rng(1)
    points = np.round(rng.uniform(0, 10, size=(2000, 3)) * 2**20) / 2**20
    base = voxel_downsample(points, 0.5)
    moved = voxel_downsample(points + 1e6, 0.5)
    assert np.array_equal(base.keys, moved.keys) and np.array_equal(base.order, moved.order)
    assert np.allclose(moved.points - 1e6, base.points, rtol=0, atol=1e-9)
    scaled = voxel_downsample(points * 1e-3, 0.5e-3)
    assert np.array_equal(base.splat_to_voxel, scaled.splat_to_voxel)
    assert np.allclose(scaled.points, base.points * 1e-3, rtol=1e-12, atol=0)


def test_voxel_grid_degenerate_inputs():
    one = voxel_downsample(np.array([[1e6, -3.0, 2.5]]), 0.1)
    assert len(one) == 1 and np.array_equal(one.points, [[1e6, -3.0, 2.5]])
    assert one.order.tolist() == [0] and one.offsets.tolist() == [0, 1]
    same = voxel_downsample(np.repeat([[0.5, 0.5, 0.5]], 7, axis=0), 0.1)
    assert len(same) == 1 and same.members(0).tolist() == list(range(7))
    empty = voxel_downsample(np.zeros((0, 3)), 0.1)
    assert len(empty) == 0 and empty.offsets.tolist() == [0]
    # a voxel far smaller than the extent: the sparse (np.unique) path gives the same grouping
    rng = np.random.default_rng(2)
    pts = rng.uniform(0, 1, size=(500, 3))
    fine = voxel_downsample(pts, 1e-4)
    keys, _, _ = _brute_grid(pts, 1e-4)
    assert [tuple(k) for k in fine.keys] == keys
    for bad in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(ValueError):
            voxel_downsample(pts, bad)
    with pytest.raises(ValueError):
        voxel_downsample(np.array([[0.0, np.nan, 1.0]]), 0.1)
    with pytest.raises(ValueError):
        voxel_downsample(pts, 0.1, weights=-np.ones(500))


def test_splat_normals_are_the_shortest_axis_of_R():
    rng = np.random.default_rng(3)
    quats = rng.normal(size=(500, 4))
    quats[0] = 0.0  # zero quaternion: identity
    scales = rng.normal(size=(500, 3))
    rot = quat_to_rotmat(quats).astype(np.float64)
    ref = rot[np.arange(500), :, np.argmin(scales, axis=1)]
    assert np.allclose(splat_normals(quats, scales), ref, atol=1e-6)
    assert np.allclose(splat_normals(rot, scales), ref, atol=1e-12)
    assert np.allclose(np.linalg.norm(splat_normals(quats, scales), axis=1), 1.0)


def _flat_splats_on(points, normals, rng):
    """Quaternions whose local z axis is the given normal (random spin), z the thinnest scale."""
    n = len(points)
    z = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    a = np.where(np.abs(z[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    x = np.cross(a, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    spin = rng.uniform(0, 2 * np.pi, n)[:, None]
    y = np.cross(z, x)
    x, y = np.cos(spin) * x + np.sin(spin) * y, -np.sin(spin) * x + np.cos(spin) * y
    rot = np.stack([x, y, z], axis=2)  # columns are the local axes
    scales_log = np.log(np.tile([0.05, 0.04, 0.001], (n, 1)))
    sign = np.where(rng.uniform(size=n) < 0.5, -1.0, 1.0)  # splat normals have no sign
    rot[:, :, 2] *= sign[:, None]
    rot[:, :, 1] *= sign[:, None]  # keep det = +1
    return rot, scales_log


def test_plane_of_flat_splats_gives_one_consistent_normal():
    rng = np.random.default_rng(4)
    uv = rng.uniform(-1, 1, size=(4000, 2))
    plane_n = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    e1 = np.cross(plane_n, [1.0, 0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(plane_n, e1)
    points = uv[:, :1] * e1 + uv[:, 1:] * e2 + 5.0
    rot, scales_log = _flat_splats_on(points, np.tile(plane_n, (4000, 1)), rng)
    grid = voxel_downsample(points, 0.1)
    normals = voxel_normals(grid, rot, scales_log, weights=rng.uniform(0.1, 1, 4000))
    dots = normals @ plane_n
    assert np.allclose(np.abs(dots), 1.0, atol=1e-9)
    assert np.all(dots > 0) or np.all(dots < 0)  # one sign for the whole (connected) plane


@pytest.mark.parametrize("orient", ["mst", "centroid"])
def test_sphere_normals_point_outward(orient):
    rng = np.random.default_rng(5)
    d = rng.normal(size=(6000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    centre = np.array([1e3, -2e3, 0.5])
    points = centre + 2.0 * d
    rot, scales_log = _flat_splats_on(points, d, rng)
    grid = voxel_downsample(points, 0.2)
    normals = voxel_normals(grid, rot, scales_log, orient=orient)
    radial = grid.points - centre
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", normals, radial) > 0.9)


def test_mst_orientation_flips_a_scrambled_field_back():
    rng = np.random.default_rng(6)
    t = rng.uniform(0, 4 * np.pi, 3000)
    points = np.stack([np.cos(t) * 3, np.sin(t) * 3, rng.uniform(0, 2, 3000)], axis=1)  # cylinder
    outward = np.stack([np.cos(t), np.sin(t), np.zeros(3000)], axis=1)
    scrambled = outward * np.where(rng.uniform(size=3000) < 0.5, -1.0, 1.0)[:, None]
    fixed = orient_mst(points, scrambled, radius=0.5)
    assert np.array_equal(np.abs(fixed), np.abs(scrambled))
    assert np.all(np.einsum("ij,ij->i", fixed, outward) > 0)


def test_voxel_normals_degenerate_inputs_are_finite():
    rng = np.random.default_rng(7)
    # a single splat: its own shortest axis (canonical sign, away from the centroid = itself)
    grid = voxel_downsample(np.array([[0.0, 0.0, 0.0]]), 0.1)
    n = voxel_normals(grid, np.array([[1.0, 0, 0, 0]]), np.log([[0.1, 0.01, 0.2]]))
    assert np.allclose(np.abs(n), [[0.0, 1.0, 0.0]])
    # all-zero weights, duplicated splats, collinear centres
    pts = np.repeat(np.stack([np.linspace(0, 1, 50)] * 3, axis=1), 3, axis=0)
    quats = rng.normal(size=(150, 4))
    scales = rng.normal(size=(150, 3))
    grid = voxel_downsample(pts, 0.05)
    for orient in ("mst", "centroid", "none"):
        n = voxel_normals(grid, quats, scales, weights=np.zeros(150), orient=orient)
        assert np.all(np.isfinite(n)) and np.allclose(np.linalg.norm(n, axis=1), 1.0)
    with pytest.raises(ValueError):
        voxel_normals(grid, quats, scales, orient="up")
    with pytest.raises(ValueError):
        voxel_normals(grid, quats[:10], scales[:10])


def test_voxel_normal_follows_the_heavier_members():
    """Two splats in one voxel, thin along z and along x: the weighted principal axis wins."""
    grid = voxel_downsample(np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]]), 1.0)
    quats = np.array([[1.0, 0, 0, 0], [1.0, 0, 0, 0]])
    scales_log = np.log([[1.0, 1.0, 0.01], [0.01, 1.0, 1.0]])  # normals e_z and e_x
    for weights, expect in (([1.0, 0.2], [0, 0, 1.0]), ([0.2, 1.0], [1.0, 0, 0])):
        n = voxel_normals(grid, quats, scales_log, weights=np.array(weights), orient="none")
        assert np.allclose(np.abs(n), [expect], atol=1e-12)
