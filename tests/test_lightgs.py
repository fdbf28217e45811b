"""LightGSPrune against a direct dense computation: every pixel × every projected splat, front to back."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from harness.core.cameras import Camera
from methods import PruneContext, get_pruner
from methods.lightgs.significance import volume_factor
from renderers.projection import project_gaussians
from tests.scene_factory import random_scene


def _scene(n=120, seed=4):
    s = random_scene(n, sh_degree=0, seed=seed)
    s.scales_log[:] += 2.0
    s.opacity_logit[:] += 2.0
    s.means[:5] = (0.0, 40.0, 0.0)  # far outside every view below
    return s


def _cams():
    up = np.array([0.0, -1.0, 0.0])
    eyes = [(0.3, -0.4, -4.0), (3.5, -1.0, 1.0), (-2.0, -2.5, 2.5)]
    return [Camera.look_at(np.array(e), np.zeros(3), up, fov_y_deg=50.0, width=64, height=48, name=f"c{i}")
            for i, e in enumerate(eyes)]


def dense_significance(scene, cams, early_stop):
    """Σ_views Σ_pixels o_j·T_j, brute force over all pixels and the projected splats in depth order."""
    total = np.zeros(len(scene))
    for cam in cams:
        with torch.no_grad():
            p = project_gaussians(scene, cam, device="cpu")
        order = np.lexsort((p.ids.numpy(), p.depths.numpy()))
        m2d, con, rad = p.means2d.numpy(), p.conics.numpy(), p.radii.numpy()
        op, ids = p.opacities.numpy(), p.ids.numpy()
        for y in range(cam.height):
            for x in range(cam.width):
                t = 1.0
                for k in order:
                    dx, dy = np.float32(x) - m2d[k, 0], np.float32(y) - m2d[k, 1]
                    if abs(dx) > rad[k] or abs(dy) > rad[k]:
                        continue
                    power = np.float32(-0.5) * (con[k, 0] * dx * dx + con[k, 2] * dy * dy) - con[k, 1] * dx * dy
                    alpha = min(0.99, float(op[k]) * float(np.exp(power)))
                    if power > 0 or alpha < 1 / 255:
                        continue
                    if early_stop and t * (1 - alpha) < 1e-4:
                        break
                    total[ids[k]] += float(op[k]) * t
                    t *= 1 - alpha
    return total


@pytest.mark.parametrize("early_stop", [True, False])
def test_matches_dense_computation(early_stop):
    scene, cams = _scene(), _cams()
    scales = np.exp(scene.scales_log.astype(np.float64))
    vol = scales.prod(1)
    v_ref = np.sort(vol)[::-1][int(0.9 * len(vol))]
    expect = dense_significance(scene, cams, early_stop) * (vol / v_ref) ** 0.1
    ctx = PruneContext(params={"train_longest_side": 0, "early_stop": early_stop}, cameras=cams)
    got = get_pruner("lightgs").score(scene, ctx)
    assert (expect > 0).sum() > 60 and (expect == 0).sum() > 0  # visible and invisible splats both present
    np.testing.assert_allclose(got, expect, rtol=2e-5, atol=1e-6)


def test_volume_reference_is_ninety_percent_down_the_descending_sort():
    logs = np.log(np.arange(1, 11, dtype=np.float64))[:, None] * np.array([[1.0, 0.0, 0.0]])
    # volumes 1..10; descending [10, 9, ..., 1]; index int(10·0.9) = 9 -> V_ref = 1
    np.testing.assert_allclose(volume_factor(logs, 0.1), np.arange(1, 11) ** 0.1)
    np.testing.assert_allclose(volume_factor(logs - 50.0, 0.1), np.arange(1, 11) ** 0.1)  # no underflow


def test_resolution_parameter_resizes_the_views():
    scene, cams = _scene(60), _cams()
    spec = get_pruner("lightgs")
    full = spec.score(scene, PruneContext(params={"train_longest_side": 0}, cameras=cams))
    half = spec.score(scene, PruneContext(params={"train_longest_side": 32}, cameras=cams))
    # Σ over pixels scales with the pixel count: about 4× fewer pixels at half the side
    ratio = half[full > 0].sum() / full[full > 0].sum()
    assert 0.15 < ratio < 0.4


def test_needs_cameras():
    spec = get_pruner("lightgs")
    assert spec.needs == frozenset({"cameras"})
    with pytest.raises(RuntimeError, match="needs cameras"):
        spec.score(_scene(10), PruneContext())
