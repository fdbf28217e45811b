"""The single-sweep significance (renderers.sweep) against the torch projection and the pixel-pair
compositing it replaces: the same projected records and the same Σ o·T, bit for bit."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from harness.core.cameras import Camera
from methods.lightgs.significance import resolve_backend, significance
from renderers import sweep
from renderers.pixel_pairs import build_pairs, composite
from renderers.projection import project_gaussians
from tests.scene_factory import random_scene
from tests.test_lightgs import _cams, dense_significance
from tests.test_lightgs import _scene as _small_scene


def _scene(n=2000, seed=3):
    s = random_scene(n, sh_degree=1, seed=seed)
    s.scales_log[:] += 1.5  # overlapping splats, so early termination engages
    s.opacity_logit[:] += 2.0
    s.means[:10] = (0.0, 0.0, -9.0)  # behind the first camera
    s.means[10:20] = (40.0, 0.0, 0.0)  # off every image
    s.quats[20:25] = 0.0  # read as the identity rotation
    s.scales_log[25:30] = 60.0  # overflowing scales: dropped
    s.means[30] = np.nan  # dropped
    s.opacity_logit[31:40] = -9.0  # below the α threshold everywhere
    s.means[40:60] = s.means[60:80]  # exact depth ties: broken by scene index
    return s


def _views():
    up = np.array([0.0, -1.0, 0.0])
    cams = [Camera.look_at(np.array(e), np.zeros(3), up, fov_y_deg=f, width=w, height=h, name=f"v{i}")
            for i, (e, f, w, h) in enumerate([((0.2, -0.3, -4.0), 50.0, 64, 48), ((3.0, -1.0, 1.5), 70.0, 37, 53),
                                              ((0.1, 0.0, 1.2), 90.0, 48, 48)])]
    cams.append(replace(cams[0], cx=20.3, cy=31.9, name="off-centre"))
    return cams


def _torch_records(scene, cam):
    with torch.no_grad():
        p = project_gaussians(scene, cam, device="cpu")
    rec = torch.cat([p.means2d, p.conics, p.radii[:, None], p.opacities[:, None]], 1).numpy()
    return p, rec


@pytest.mark.parametrize("view", range(4))
def test_projection_is_the_torch_projection_bit_for_bit(view):
    scene, cam = _scene(), _views()[view]
    p, rec = _torch_records(scene, cam)
    ids, mine, depths = sweep.project(sweep.Geometry(scene), cam)
    assert len(ids) > 100
    np.testing.assert_array_equal(ids, p.ids.numpy())
    np.testing.assert_array_equal(mine, rec)
    np.testing.assert_array_equal(depths, p.depths.numpy())


@pytest.mark.parametrize("early_stop", [True, False])
@pytest.mark.parametrize("view", range(4))
def test_sums_are_the_pair_compositing_bit_for_bit(view, early_stop):
    scene, cam = _scene(), _views()[view]
    with torch.no_grad():
        pairs = build_pairs(project_gaussians(scene, cam, device="cpu"))
    expect = composite(pairs, early_stop=early_stop, stats=True).opacity_t
    ids, sums = sweep.opacity_transmittance(sweep.Geometry(scene), cam, early_stop=early_stop)
    np.testing.assert_array_equal(ids, pairs.ids)
    np.testing.assert_array_equal(sums, expect)
    assert (sums > 0).sum() > 50


def test_early_termination_changes_this_scene():
    scene, cam = _scene(), _views()[0]
    geom = sweep.Geometry(scene)
    assert not np.array_equal(sweep.opacity_transmittance(geom, cam, early_stop=True)[1],
                              sweep.opacity_transmittance(geom, cam, early_stop=False)[1])


@pytest.mark.parametrize("early_stop", [True, False])
def test_significance_backend_equals_pairs_and_the_dense_computation(early_stop):
    scene, cams = _small_scene(), _cams()
    got = significance(scene, cams, longest_side=0, early_stop=early_stop, backend="sweep")
    np.testing.assert_array_equal(got, significance(scene, cams, longest_side=0, early_stop=early_stop,
                                                    backend="pairs"))
    np.testing.assert_allclose(got, dense_significance(scene, cams, early_stop), rtol=2e-5, atol=1e-6)


def test_auto_backend_is_the_sweep_on_the_cpu_only():
    assert resolve_backend("auto", "cpu") == "sweep"
    assert resolve_backend("auto", "cuda") == "reference"
    with pytest.raises(ValueError, match="runs on the CPU"):
        significance(_small_scene(), _cams(), backend="sweep", device="meta")


@pytest.mark.parametrize("seed", range(3))
def test_depth_order_is_the_stable_argsort(seed):
    rng = np.random.default_rng(seed)
    d = rng.uniform(0.2, 50.0, 5000).astype(np.float32)
    d[::7] = d[3]  # ties
    d[1::11] = np.float32(0.2000001)
    np.testing.assert_array_equal(sweep.depth_order(d), np.argsort(d, kind="stable"))
    assert len(sweep.depth_order(np.zeros(0, np.float32))) == 0


def test_nothing_in_view_gives_nothing():
    scene = _scene()
    away = Camera.look_at(np.array([0.0, 0.0, 30.0]), np.array([0.0, 0.0, 60.0]), np.array([0.0, -1.0, 0.0]),
                          width=32, height=24)
    ids, sums = sweep.opacity_transmittance(sweep.Geometry(scene), away)
    assert len(ids) == len(sums) == 0
    assert significance(scene, [away], longest_side=0).sum() == 0.0
