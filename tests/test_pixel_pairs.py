"""Pair compositing (renderers.pixel_pairs) against the reference tile rasterizer: image, per-splat
statistics and the opacity gradient must agree (the rasterizer is itself checked against dense numpy)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from harness.core.cameras import Camera
from renderers.pixel_pairs import build_pairs, composite, render_pairs
from renderers.projection import SplatTensors, project_gaussians
from renderers.reference import rasterize
from tests.scene_factory import random_scene

BG = (0.2, 0.3, 0.4)


def _scene(n=300, seed=1):
    s = random_scene(n, sh_degree=1, seed=seed)
    s.scales_log[:] += 2.0  # ~0.13 std-devs in a unit cloud: overlapping splats
    s.opacity_logit[:] += 3.0  # mostly opaque, so early termination engages
    return s


def _cam(w=41, h=29, eye=(0.3, -0.4, -4.0)):
    return Camera.look_at(np.array(eye), np.zeros(3), np.array([0.0, -1.0, 0.0]), fov_y_deg=50.0, width=w, height=h)


def _pairs(scene, cam):
    with torch.no_grad():
        return build_pairs(project_gaussians(scene, cam, device="cpu"))


def _full(pairs, values, n):
    out = np.zeros(n, np.asarray(values).dtype)
    out[pairs.ids] = values
    return out


@pytest.mark.parametrize("early_stop", [False, True])
def test_image_and_statistics_match_reference(early_stop):
    scene, cam = _scene(), _cam()
    with torch.no_grad():
        ref = rasterize(scene, cam, BG, device="cpu", stats=True, early_stop=early_stop)
    pairs = _pairs(scene, cam)
    out = composite(pairs, background=BG, stats=True, early_stop=early_stop)
    np.testing.assert_allclose(out.image, ref.image.numpy(), atol=2e-6)
    np.testing.assert_array_equal(_full(pairs, out.hits, len(scene)), ref.hits.numpy())
    np.testing.assert_allclose(_full(pairs, out.opacity_t, len(scene)), ref.opacity_t.numpy(), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(_full(pairs, out.alpha_t, len(scene)), ref.alpha_t.numpy(), rtol=1e-5, atol=1e-5)


def test_early_stop_actually_cuts_pairs_in_this_scene():
    scene, cam = _scene(), _cam()
    pairs = _pairs(scene, cam)
    full = composite(pairs, stats=True, early_stop=False)
    cut = composite(pairs, stats=True, early_stop=True)
    assert cut.hits.sum() < full.hits.sum() - 50
    assert len(pairs) == full.hits.sum()  # every stored pair passes the α test at the stored opacities


@pytest.mark.parametrize("early_stop", [False, True])
def test_opacity_gradient_matches_autograd_through_reference(early_stop):
    scene, cam = _scene(seed=2), _cam()
    n = len(scene)
    gate = torch.rand(n, generator=torch.Generator().manual_seed(0))
    base = torch.sigmoid(torch.tensor(scene.opacity_logit))
    weights = torch.rand(cam.height, cam.width, 3, generator=torch.Generator().manual_seed(1))

    g_ref = gate.clone().requires_grad_(True)
    img_ref = rasterize(SplatTensors.from_scene(scene, device="cpu"), cam, BG, opacities=base * g_ref,
                        early_stop=early_stop).image
    (img_ref * weights).sum().backward()

    pairs = _pairs(scene, cam)
    g = gate.clone().requires_grad_(True)
    img = render_pairs(pairs, (base * g)[torch.from_numpy(pairs.ids)], BG, early_stop=early_stop)
    (img * weights).sum().backward()

    np.testing.assert_allclose(img.detach().numpy(), img_ref.detach().numpy(), atol=2e-6)
    assert g_ref.grad.abs().max() > 1.0  # a real signal
    np.testing.assert_allclose(g.grad.numpy(), g_ref.grad.numpy(), rtol=1e-4, atol=1e-5)


def test_view_with_nothing_in_front_renders_the_background():
    scene = _scene()
    cam = _cam(eye=(0.0, 0.0, -4.0))
    away = Camera.look_at(cam.center, cam.center - np.array([0.0, 0.0, 1.0]), np.array([0.0, -1.0, 0.0]),
                          fov_y_deg=50.0, width=16, height=12)
    pairs = _pairs(scene, away)
    out = composite(pairs, background=BG, stats=True)
    assert len(pairs) == 0
    np.testing.assert_allclose(out.image, np.broadcast_to(np.float32(BG), out.image.shape))
