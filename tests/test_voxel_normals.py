"""Voxel grid (CSR, means, invariances) and voxel normals (shortest axis, aggregation, orientation)."""

from __future__ import annotations

import numpy as np
import pytest

from harness.core.scene import quat_to_rotmat
from methods.betadesc.grid import build_grid
from methods.betadesc.normals import orient_mst, splat_normals, voxel_normals


def _brute_grid(points, voxel_fraction):
    """Reference by dictionaries: cell -> sorted members, member mean in voxel units."""
    lo = points.min(axis=0)
    h = voxel_fraction * np.linalg.norm(points.max(axis=0) - lo)
    t = (points - lo) / h
    groups = {}
    for i, ti in enumerate(t):
        groups.setdefault(tuple(np.floor(ti).astype(np.int64)), []).append(i)
    keys = sorted(groups)
    return keys, [groups[k] for k in keys], np.array([t[groups[k]].mean(axis=0) for k in keys])


def test_grid_matches_brute_force():
    rng = np.random.default_rng(0)
    points = rng.normal(size=(3000, 3)) * [1.0, 0.5, 2.0]
    points[100:150] = points[:50]  # duplicates
    grid = build_grid(points, 0.05)
    keys, members, means = _brute_grid(points, 0.05)
    cells = [tuple(int(c) for c in np.floor(grid.points[v])) for v in range(grid.m)]
    assert cells == keys
    assert np.array_equal(grid.counts, [len(m) for m in members])
    for v, mem in enumerate(members):
        assert np.all(grid.splat_voxel[mem] == v)
    assert np.allclose(grid.points, means, rtol=0, atol=1e-6)  # sums of 2⁻²⁴-quantised offsets


def test_grid_far_from_origin_scaled_and_permuted():
    """Multiples of 2⁻²⁰ below 16: adding 1e6 is exact, so the grid must be identical; a permutation
    of the splats permutes nothing at voxel level (exact sums)."""
    rng = np.random.default_rng(1)
    points = np.round(rng.uniform(0, 10, size=(2000, 3)) * 2**20) / 2**20
    base = build_grid(points, 0.05)
    moved = build_grid(points + 1e6, 0.05)
    assert np.array_equal(base.keys, moved.keys) and np.array_equal(base.splat_voxel, moved.splat_voxel)
    assert np.allclose(moved.points, base.points, rtol=0, atol=1e-6)
    scaled = build_grid(points * 1e-3, 0.05)
    assert np.array_equal(base.splat_voxel, scaled.splat_voxel)
    perm = rng.permutation(2000)
    shuffled = build_grid(points[perm], 0.05)
    assert np.array_equal(shuffled.points, base.points) and np.array_equal(shuffled.splat_voxel, base.splat_voxel[perm])


def test_grid_degenerate_inputs():
    one = build_grid(np.array([[1e6, -3.0, 2.5]]), 0.1)
    assert one.m == 1 and one.h == 1.0  # zero diagonal: a unit voxel
    same = build_grid(np.repeat([[0.5, 0.5, 0.5]], 7, axis=0), 0.1)
    assert same.m == 1 and same.counts.tolist() == [7.0]
    rng = np.random.default_rng(2)
    pts = rng.uniform(0, 1, size=(500, 3))
    fine = build_grid(pts, 1e-5)  # far more cells than splats: the sparse path gives the same grouping
    keys, _, _ = _brute_grid(pts, 1e-5)
    assert fine.m == len(keys)
    for bad in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(ValueError):
            build_grid(pts, bad)
    for bad_points in (np.zeros((0, 3)), np.array([[0.0, np.nan, 1.0]]), np.zeros((4, 2))):
        with pytest.raises(ValueError):
            build_grid(bad_points, 0.1)


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
    grid = build_grid(points, 0.04)
    normals = voxel_normals(grid, rot, scales_log, 5.0)
    dots = normals @ plane_n
    assert np.allclose(np.abs(dots), 1.0, atol=1e-9)
    assert np.all(dots > 0) or np.all(dots < 0)  # one sign for the whole (connected) plane


def test_sphere_normals_point_outward():
    rng = np.random.default_rng(5)
    d = rng.normal(size=(6000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    centre = np.array([1e3, -2e3, 0.5])
    points = centre + 2.0 * d
    rot, scales_log = _flat_splats_on(points, d, rng)
    grid = build_grid(points, 0.04)
    normals = voxel_normals(grid, rot, scales_log, 5.0)
    radial = grid.lo + grid.points * grid.h - centre
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
    # a single splat: its own shortest axis
    grid = build_grid(np.array([[0.0, 0.0, 0.0]]), 0.1)
    n = voxel_normals(grid, np.array([[1.0, 0, 0, 0]]), np.log([[0.1, 0.01, 0.2]]), 5.0)
    assert np.allclose(np.abs(n), [[0.0, 1.0, 0.0]])
    # duplicated splats on a line
    pts = np.repeat(np.stack([np.linspace(0, 1, 50)] * 3, axis=1), 3, axis=0)
    quats = rng.normal(size=(150, 4))
    scales = rng.normal(size=(150, 3))
    grid = build_grid(pts, 0.05)
    n = voxel_normals(grid, quats, scales, 5.0)
    assert np.all(np.isfinite(n)) and np.allclose(np.linalg.norm(n, axis=1), 1.0)
    with pytest.raises(ValueError):
        voxel_normals(grid, quats[:10], scales[:10], 5.0)


def test_voxel_normal_is_the_members_principal_axis():
    """Three splats thin along z and one thin along x share a voxel: the mean tensor's axis is z."""
    grid = build_grid(np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.01, 0.01, 0.0]]), 1.0)
    quats = np.tile([1.0, 0, 0, 0], (4, 1))
    scales_log = np.log([[1.0, 1.0, 0.01], [1.0, 1.0, 0.01], [1.0, 1.0, 0.01], [0.01, 1.0, 1.0]])
    assert np.allclose(np.abs(voxel_normals(grid, quats, scales_log, 5.0)), [[0, 0, 1.0]], atol=1e-12)
