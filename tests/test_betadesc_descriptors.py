"""HSFH building blocks: voxel grid, normals, descriptor blocks, statistics, interpolation."""

from __future__ import annotations

import numpy as np
import pytest

from harness.core.scene import SH_C0, GaussianScene
from methods.betadesc.grid import build_grid
from methods.betadesc.hsfh import band_fractions, compute_hsfh, normalise_fpfh
from methods.betadesc.interpolate import interpolate_to_splats
from methods.betadesc.nodesc import splat_statistics
from methods.betadesc.normals import voxel_normals
from methods.betadesc.statistics import (
    geometric_spread,
    robust_unit,
    voxel_statistics,
)
from tests.scene_factory import random_scene


def _scene(means, quats=None, scales_log=None, sh_rest_k=0, seed=0) -> GaussianScene:
    rng = np.random.default_rng(seed)
    n = len(means)
    return GaussianScene.from_arrays(
        means=means,
        scales_log=rng.normal(-4, 0.3, (n, 3)) if scales_log is None else scales_log,
        quats=rng.normal(size=(n, 4)) if quats is None else quats,
        opacity_logit=rng.normal(0, 1, n),
        sh_dc=rng.normal(0, 1, (n, 3)),
        sh_rest=rng.normal(0, 0.1, (n, sh_rest_k, 3)),
    )


def test_grid_voxel_points_are_member_means_in_voxel_units():
    scene = random_scene(2000, seed=1)
    grid = build_grid(scene.means, 0.05)
    x = scene.means.astype(np.float64)
    lo = x.min(0)
    diag = np.linalg.norm(x.max(0) - lo)
    assert grid.h == pytest.approx(0.05 * diag)
    t = (x - lo) / grid.h
    np.testing.assert_array_equal(np.floor(grid.points[grid.splat_voxel]), np.floor(t))
    for j in (0, grid.m // 2, grid.m - 1):
        members = grid.splat_voxel == j
        np.testing.assert_allclose(grid.points[j], t[members].mean(0), atol=1e-6)
        assert grid.counts[j] == members.sum()
    assert np.all(np.diff(grid.keys) > 0)


def test_grid_dense_and_sorted_paths_agree():
    from methods.betadesc.grid import occupied_cells

    key = np.random.default_rng(0).integers(0, 10**6, 5000)
    dense = occupied_cells(key, 10**6)  # a small grid: dense cell table
    by_sort = occupied_cells(key, 10**12)  # claimed huge grid: np.unique path
    np.testing.assert_array_equal(dense[0], by_sort[0])
    np.testing.assert_array_equal(dense[1], by_sort[1])
    np.testing.assert_array_equal(dense[0][dense[1]], key)
    assert np.all(np.diff(dense[0]) > 0)


def test_plane_normals_are_the_plane_normal_oriented_consistently():
    rng = np.random.default_rng(3)
    n = 3000
    means = np.c_[rng.uniform(-1, 1, (n, 2)), np.zeros(n)]
    scales_log = np.c_[np.full((n, 2), -3.0), np.full(n, -8.0)]  # flat discs in the plane
    angle = rng.uniform(0, 2 * np.pi, n)  # random in-plane rotations about z keep the short axis on z
    quats = np.c_[np.cos(angle / 2), np.zeros(n), np.zeros(n), np.sin(angle / 2)]
    scene = _scene(means, quats, scales_log)
    grid = build_grid(scene.means, 0.05)
    normals = voxel_normals(grid, scene.quats, scene.scales_log, 3.0)
    np.testing.assert_allclose(np.abs(normals[:, 2]), 1.0, atol=1e-9)
    assert np.all(normals[:, 2] == normals[0, 2])  # one orientation for a flat plane


def test_fpfh_normalisation_and_geometric_spread():
    raw = np.zeros((3, 33))
    raw[0, [5, 16, 27]] = 100.0  # one bin per angle: a perfectly regular (planar) neighbourhood
    raw[1] = 1.0  # all bins equal: maximal spread
    g = normalise_fpfh(raw)
    np.testing.assert_allclose(g[:2].reshape(2, 3, 11).sum(2), 1.0)
    assert np.all(g[2] == 0)
    np.testing.assert_allclose(geometric_spread(g), [0.0, 1.0, 0.0], atol=1e-12)


def test_plane_is_less_unique_than_a_sphere():
    rng = np.random.default_rng(4)
    n = 4000
    plane = np.c_[rng.uniform(-1, 1, (n, 2)), np.zeros(n)]
    sphere = rng.normal(size=(n, 3))
    sphere /= np.linalg.norm(sphere, axis=1, keepdims=True)
    spreads = []
    for means in (plane, sphere):
        # the normal of each splat is its radial / z direction: align the short axis with it
        normal = means / np.maximum(np.linalg.norm(means, axis=1, keepdims=True), 1e-12)
        normal[means[:, 2] == 0] = (0, 0, 1)
        z = np.array([0.0, 0.0, 1.0])
        axis = np.cross(z, normal)
        s = np.linalg.norm(axis, axis=1)
        c = normal @ z
        half = np.arctan2(s, c) / 2
        axis = np.divide(axis, s[:, None], out=np.zeros_like(axis), where=s[:, None] > 0)
        quats = np.c_[np.cos(half), axis * np.sin(half)[:, None]]
        scene = _scene(means, quats, np.c_[np.full((n, 2), -3.0), np.full(n, -8.0)])
        desc = compute_hsfh(scene, 0.04, 5.0, 100, 8)
        spreads.append(np.median(geometric_spread(desc.geometric)))
    assert spreads[0] < 0.5 * spreads[1]


def test_band_fractions_sum_to_one_and_skip_absent_bands():
    scene = random_scene(50, sh_degree=3, seed=5)
    f = band_fractions(scene)
    assert f.shape == (50, 4)
    np.testing.assert_allclose(f.sum(1), 1.0)
    p1 = (scene.sh_rest[:, 0:3].astype(np.float64) ** 2).sum((1, 2))
    total = (scene.sh_dc.astype(np.float64) ** 2).sum(1) + (scene.sh_rest.astype(np.float64) ** 2).sum((1, 2))
    np.testing.assert_allclose(f[:, 1], p1 / total, rtol=1e-12)
    assert band_fractions(random_scene(5, sh_degree=0)).shape == (5, 1)


def test_colour_histogram_counts_the_neighbourhood():
    scene = random_scene(800, sh_degree=1, seed=6)
    desc = compute_hsfh(scene, 0.1, 2.0, 50, 4)
    np.testing.assert_allclose(desc.colour.sum(2), 1.0)
    j = 0
    nb = desc.indices[desc.indptr[j]:desc.indptr[j + 1]]
    members = np.isin(desc.grid.splat_voxel, nb)
    c = np.clip(0.5 + SH_C0 * scene.sh_dc[members].astype(np.float64), 0, 1)
    bins = np.minimum((c * 4).astype(int), 3)
    expect = np.stack([np.bincount(bins[:, ch], minlength=4) for ch in range(3)]) / members.sum()
    np.testing.assert_allclose(desc.colour[j], expect, atol=1e-15)
    f = band_fractions(scene)[members]
    np.testing.assert_allclose(desc.spectrum[j], f.mean(0), atol=1e-6)
    np.testing.assert_allclose(desc.spectrum_var[j], f.var(0), atol=1e-6)


def test_robust_unit_is_affine_invariant_and_clipped():
    x = np.random.default_rng(7).normal(size=1000)
    u = robust_unit(x)
    assert u.min() == 0 and u.max() == 1
    np.testing.assert_allclose(robust_unit(3e5 * x - 7e3), u, atol=1e-9)
    np.testing.assert_array_equal(robust_unit(np.full(10, 3.0)), 0.5)
    assert robust_unit(np.zeros(0)).shape == (0,)


def test_statistics_in_unit_interval():
    scene = random_scene(1500, sh_degree=2, seed=8)
    desc = compute_hsfh(scene, 0.05, 3.0, 60, 8)
    for stat in (voxel_statistics(desc), splat_statistics(scene)):
        assert np.isfinite(stat).all() and (stat >= 0).all() and (stat <= 1).all()


def test_interpolation_reproduces_constants_and_single_voxel_values():
    scene = random_scene(3000, seed=9)
    grid = build_grid(scene.means, 0.05)
    values = np.c_[np.full(grid.m, 0.7), np.arange(grid.m, dtype=float)]
    out, w = interpolate_to_splats(grid, values)
    np.testing.assert_allclose(out[:, 0], 0.7, atol=1e-15)
    assert ((w > np.exp(-1.5) - 1e-12) & (w <= 1)).all()
    # a splat alone in its stencil takes its voxel's value exactly
    lonely = _scene(np.array([[0.0, 0, 0], [10.0, 10, 10]]))
    g2 = build_grid(lonely.means, 0.01)
    out2, w2 = interpolate_to_splats(g2, np.array([[1.0], [2.0]]))
    np.testing.assert_array_equal(out2[:, 0], [1.0, 2.0])
    np.testing.assert_allclose(w2, np.exp(-0.5 * np.sum((g2.t - g2.points) ** 2, 1)))


def test_interpolation_matches_brute_force_kernel_weights():
    scene = random_scene(400, seed=10)
    grid = build_grid(scene.means, 0.08)
    values = np.random.default_rng(1).random((grid.m, 2))
    out, w = interpolate_to_splats(grid, values)
    cells = np.floor(grid.points).astype(int)
    for i in range(0, 400, 37):
        base = np.floor(grid.t[i] - 0.5).astype(int)
        sel = np.all((cells >= base) & (cells <= base + 1), axis=1)
        k = np.exp(-0.5 * ((grid.t[i] - grid.points[sel]) ** 2).sum(1))
        np.testing.assert_allclose(out[i], k @ values[sel] / k.sum(), rtol=1e-12)
        assert w[i] == pytest.approx(min(1.0, k.sum()), rel=1e-12)
