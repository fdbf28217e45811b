"""FPFH and the hybrid search against open3d and a brute-force reference.

Tolerance: histogram values (scale 100) agree with open3d within 1e-9 (summation order and a
reciprocal 1/d² differ). Clouds are continuous random or max_nn exceeds the point count, so no two
neighbours tie at the max_nn boundary (where both searches may legitimately keep different points).
"""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from methods.betadesc.fpfh import _alpha_bin, compute_fpfh
from methods.betadesc.neighbors import hybrid_search

TOL = 1e-9

try:
    import open3d as o3d
except ImportError as exc:  # the system libusb open3d links against may be missing
    o3d = None
    O3D_REASON = f"open3d is not importable: {exc}"
else:
    O3D_REASON = ""

needs_o3d = pytest.mark.skipif(o3d is None, reason=O3D_REASON or "open3d present")


def _o3d_fpfh(points, normals, radius, max_nn):
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pcd.normals = o3d.utility.Vector3dVector(normals)
    param = o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=max_nn)
    return np.asarray(o3d.pipelines.registration.compute_fpfh_feature(pcd, param).data).T


def _unit(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _brute_hybrid(points, radius, max_nn):
    """Reference: per point, the max_nn smallest (d², self first, index) with d² < r²."""
    out = []
    for i, q in enumerate(points):
        e = q - points
        d2 = e[:, 0] * e[:, 0] + e[:, 1] * e[:, 1] + e[:, 2] * e[:, 2]
        rank = np.arange(len(points))
        rank[i] = -1
        inside = np.flatnonzero(d2 < radius * radius)
        keep = inside[np.lexsort((rank[inside], d2[inside]))][:max_nn]
        out.append(dict(zip(keep.tolist(), d2[keep].tolist())))
    return out


def _as_dicts(nbh):
    d2 = nbh.squared_distances()
    return [dict(zip(nbh.index[i, : nbh.count[i]].tolist(), d2[i, : nbh.count[i]].tolist()))
            for i in range(len(nbh))]


# --------------------------------------------------------------------------- hybrid search
def test_hybrid_search_equals_brute_force_with_ties():
    """A lattice is full of exact distance ties; the search must break them by index."""
    g = np.arange(5.0)
    lattice = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    # plus exact duplicates, and a pile of 30 copies of one point (more than max_nn at distance 0)
    points = np.concatenate([lattice, lattice[:7], np.repeat(lattice[62:63], 30, axis=0)])
    for radius, max_nn in ((1.5, 8), (2.01, 20), (1.0, 3), (10.0, 200)):
        nbh = hybrid_search(points, radius, max_nn)
        assert _as_dicts(nbh) == _brute_hybrid(points, radius, max_nn)
        assert np.array_equal(nbh.index[:, 0], np.arange(len(points)))  # itself first


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    m=st.integers(1, 400),
    radius=st.sampled_from([0.5, 1.0, 1.5, 2.0, 3.0, 10.0]),
    max_nn=st.integers(1, 80),
)
def test_hybrid_search_equals_brute_force_on_tied_clouds(seed, m, radius, max_nn):
    """Integer coordinates on a 6³ lattice: many points share a d², and many repeat exactly, so
    the k-th nearest is often one of a run of ties — the selection must still cut by index."""
    points = np.random.default_rng(seed).integers(0, 6, size=(m, 3)).astype(np.float64)
    assert _as_dicts(hybrid_search(points, radius, max_nn)) == _brute_hybrid(points, radius, max_nn)


@needs_o3d
def test_hybrid_search_equals_open3d():
    rng = np.random.default_rng(3)
    points = rng.normal(size=(800, 3))
    tree = o3d.geometry.KDTreeFlann(o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points)))
    nbh = hybrid_search(points, 0.6, 25)
    ours = _as_dicts(nbh)
    for i in range(len(points)):
        k, idx, d2 = tree.search_hybrid_vector_3d(points[i], 0.6, 25)
        assert nbh.count[i] == k
        assert dict(zip(np.asarray(idx).tolist(), np.asarray(d2).tolist())) == ours[i]


def test_hybrid_search_rejects_bad_parameters():
    pts = np.zeros((3, 3))
    for radius, max_nn in ((0.0, 5), (-1.0, 5), (float("nan"), 5), (1.0, 0)):
        with pytest.raises(ValueError):
            hybrid_search(pts, radius, max_nn)
    with pytest.raises(ValueError):
        hybrid_search(np.array([[0.0, np.nan, 0.0]]), 1.0, 5)


# --------------------------------------------------------------------------- alpha bins
def _alpha_bin_reference(y, x):
    return min(max(math.floor(11 * (math.atan2(y, x) + math.pi) / (2.0 * math.pi)), 0), 10)


def test_alpha_bin_is_exact_near_edges_and_axes():
    rng = np.random.default_rng(0)
    edges = -math.pi + 2.0 * math.pi * np.arange(12) / 11.0
    angles = np.concatenate([
        rng.uniform(-math.pi, math.pi, 20000),
        (edges[:, None] + np.array([-1e-6, -1e-9, -1e-13, 0.0, 1e-13, 1e-9, 1e-6])).ravel(),
    ])
    radii = rng.uniform(1e-3, 10.0, len(angles))
    cases = list(zip(radii * np.sin(angles), radii * np.cos(angles)))
    cases += [(0.0, 1.0), (0.0, -1.0), (-0.0, -1.0), (1.0, 0.0), (-1.0, 0.0), (0.0, 0.0), (-0.0, -0.0),
              (1e-300, -1.0), (-1e-300, -1.0), (1.0, 1.0), (-1.0, -1.0)]
    got = [_alpha_bin(y, x) for y, x in cases]
    assert got == [_alpha_bin_reference(y, x) for y, x in cases]


# --------------------------------------------------------------------------- FPFH vs open3d
@needs_o3d
@pytest.mark.parametrize("seed", range(4))
def test_fpfh_matches_open3d_random(seed):
    rng = np.random.default_rng(seed)
    m = int(rng.integers(100, 1500))
    points = rng.normal(size=(m, 3)) * rng.uniform(0.5, 2.0, 3)
    normals = _unit(rng, m)
    radius = float(rng.uniform(0.2, 1.0))
    max_nn = int(rng.integers(2, 80))
    ours = compute_fpfh(points, normals, radius, max_nn)
    ref = _o3d_fpfh(points, normals, radius, max_nn)
    assert ours.shape == (m, 33) and ours.dtype == np.float64
    assert np.abs(ours - ref).max() <= TOL


@needs_o3d
def test_fpfh_matches_open3d_on_grape_small():
    from harness.io import datasets

    path = datasets.scene_path("grape-small")
    if not path.exists():
        pytest.skip(f"shared data folder absent ({path})")
    from harness.io.scenes import load_scene
    from methods.betadesc.grid import build_grid
    from methods.betadesc.normals import voxel_normals

    scene = load_scene(path)
    grid = build_grid(scene.means, 0.015)  # coordinates in voxels
    normals = voxel_normals(grid, scene.quats, scene.scales_log, 5.0)
    radius = 5.0
    ours = compute_fpfh(grid.points, normals, radius, 64)
    ref = _o3d_fpfh(grid.points, normals, radius, 64)
    assert grid.m > 200
    assert np.abs(ours - ref).max() <= TOL


@needs_o3d
@pytest.mark.parametrize("case", ["single", "duplicates", "collinear", "coplanar", "few", "pairs"])
def test_degenerate_clouds_are_finite_and_match_open3d(case):
    """max_nn ≥ M here, so the neighbourhoods are pure radius searches without boundary ties."""
    rng = np.random.default_rng(7)
    t = np.sort(rng.uniform(0.0, 1.0, 30))
    points = {
        "single": np.array([[0.3, -0.2, 5.0]]),
        "duplicates": np.repeat([[1.0, 2.0, 3.0]], 12, axis=0),
        "collinear": np.stack([t, 2 * t, -t], axis=1),
        "coplanar": np.stack([t, rng.uniform(0, 1, 30), np.zeros(30)], axis=1),
        "few": rng.normal(size=(5, 3)),
        "pairs": np.repeat(rng.normal(size=(10, 3)), 2, axis=0),  # every point twice
    }[case]
    m = len(points)
    normals = {
        "collinear": np.repeat([[1.0, 2.0, -1.0]], m, axis=0) / math.sqrt(6.0),  # parallel to the line
        "coplanar": np.repeat([[0.0, 0.0, 1.0]], m, axis=0),
    }.get(case, _unit(rng, m))
    ours = compute_fpfh(points, normals, 0.9, 64)
    assert np.all(np.isfinite(ours))
    assert np.abs(ours - _o3d_fpfh(points, normals, 0.9, 64)).max() <= TOL
    if case == "single":
        assert not ours.any()


def test_fpfh_rejects_bad_input():
    p = np.zeros((4, 3))
    with pytest.raises(ValueError):
        compute_fpfh(p, np.zeros((3, 3)), 1.0, 5)
    with pytest.raises(ValueError):
        compute_fpfh(p, np.full((4, 3), np.inf), 1.0, 5)
    with pytest.raises(ValueError):
        compute_fpfh(p, np.ones((4, 3)), 1.0, 5, neighbors=hybrid_search(p, 2.0, 5))


def test_fpfh_block_sums_and_thread_count_independence():
    rng = np.random.default_rng(11)
    points = rng.normal(size=(3000, 3))
    normals = _unit(rng, 3000)
    before = numba.get_num_threads()
    try:
        runs = []
        for threads in (1, numba.config.NUMBA_NUM_THREADS):
            numba.set_num_threads(threads)
            runs.append((compute_fpfh(points, normals, 0.5, 40), hybrid_search(points, 0.5, 40)))
    finally:
        numba.set_num_threads(before)
    (f1, n1), (f2, n2) = runs
    assert np.array_equal(f1, f2)
    assert np.array_equal(n1.index, n2.index) and np.array_equal(n1.count, n2.count)
    # every block of a point with neighbours is SPFH (sums to 100) + normalised sum (100)
    has = n1.count > 1
    blocks = f1.reshape(-1, 3, 11).sum(axis=2)
    assert np.allclose(blocks[has], 200.0, atol=1e-9)
    assert not f1[~has].any()


# --------------------------------------------------------------------------- invariances
@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    scale=st.sampled_from([1e-3, 1e3]),
    offset=st.sampled_from([1e6, -1e6]),
)
def test_fpfh_invariant_to_translation_and_scale(seed, scale, offset):
    """Coordinates are multiples of 2⁻²⁰ below 8, so adding ±1e6 is exact in float64 and the
    translated FPFH is bit-identical; scaling rounds coordinates (1e-16), so it agrees within TOL."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(20, 300))
    points = np.round(rng.uniform(0.0, 4.0, size=(m, 3)) * 2**20) / 2**20
    normals = _unit(rng, m)
    radius = float(rng.uniform(0.3, 1.5))
    max_nn = int(rng.integers(2, 40))
    base = compute_fpfh(points, normals, radius, max_nn)
    assert np.array_equal(compute_fpfh(points + offset, normals, radius, max_nn), base)
    scaled = compute_fpfh(points * scale, normals, radius * scale, max_nn)
    assert np.abs(scaled - base).max() <= TOL
