"""ConfSplatPrune: the learned Beta gate reduces the image loss, leaves invisible splats to the
regularisers alone, and is deterministic in its seed."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from harness.core.cameras import Camera
from methods import PruneContext, get_pruner
from methods.confsplat.train import (
    beta_gate,
    image_loss,
    optimise_confidence,
    prepare_views,
)
from methods.lightgs.significance import significance
from renderers.pixel_pairs import render_pairs
from tests.scene_factory import random_scene

N_HIDDEN = 8


def _scene(n=150, seed=5):
    s = random_scene(n, sh_degree=0, seed=seed)
    s.scales_log[:] += 1.5
    s.opacity_logit[:] += 1.0
    s.means[:N_HIDDEN] = (0.0, 40.0, 0.0)  # outside every training view
    s.opacity_logit[:N_HIDDEN] = 4.0  # opaque: only visibility sets them apart
    return s


def _cams():
    up = np.array([0.0, -1.0, 0.0])
    eyes = [(0.3, -0.4, -4.0), (3.5, -1.0, 1.0), (-2.0, -2.5, 2.5), (0.5, -3.0, 3.0)]
    return [Camera.look_at(np.array(e), np.zeros(3), up, fov_y_deg=50.0, width=48, height=36, name=f"c{i}")
            for i, e in enumerate(eyes)]


def _mean_image_loss(scene, cams, confidence):
    c = torch.as_tensor(confidence, dtype=torch.float32)
    losses = []
    for v in prepare_views(scene, cams, 0):
        img = render_pairs(v.pairs, v.base * c[v.ids])
        losses.append(float(image_loss(img, v.target, 0.2)))
    return float(np.mean(losses))


def test_gated_render_moves_towards_the_unpruned_render():
    scene, cams = _scene(), _cams()
    res = optimise_confidence(scene, cams, {"train_longest_side": 0, "iterations": 40, "lr": 1e-2}, seed=0)
    assert res.iterations == 40 and len(res.losses) == 40
    before = _mean_image_loss(scene, cams, np.full(len(scene), 0.5))
    after = _mean_image_loss(scene, cams, res.confidence)
    assert after < 0.85 * before
    # per view, the last visit's loss is below the first visit's
    for v in range(len(cams)):
        steps = [i for i, x in enumerate(res.views) if x == v]
        assert res.losses[steps[-1]] < res.losses[steps[0]]


def _regulariser_only(iterations, n, lr, lam_s=2e-3, lam_e=2e-3):
    """Adam on one splat's (a, b) with only the sparsity and entropy terms (their share of the means)."""
    a = torch.ones(1, requires_grad=True)
    b = torch.ones(1, requires_grad=True)
    opt = torch.optim.Adam([a, b], lr=lr, eps=1e-15, betas=(0.9, 0.999))
    for _ in range(iterations):
        c, al, be = beta_gate(a, b)
        loss = (lam_s * c.sum() + lam_e * torch.distributions.Beta(al, be).entropy().sum()) / n
        opt.zero_grad()
        loss.backward()
        opt.step()
    return float(beta_gate(a, b)[0].detach())


def test_invisible_splats_are_moved_only_by_the_regularisers():
    scene, cams = _scene(), _cams()
    params = {"train_longest_side": 0, "iterations": 60}
    res = optimise_confidence(scene, cams, params, seed=1)
    c = res.confidence
    sig = significance(scene, cams, longest_side=0, early_stop=False)
    assert (sig[:N_HIDDEN] == 0).all() and (sig[N_HIDDEN:] > 0).all()
    hidden = c[:N_HIDDEN]
    # no image gradient ever reached them: exactly the regulariser-only trajectory
    np.testing.assert_allclose(hidden, _regulariser_only(60, len(scene), 1e-3), rtol=0, atol=1e-6)
    assert hidden.max() < 0.5
    # visible splats that carry the images end higher than every invisible one
    opaque = np.flatnonzero((sig > np.percentile(sig[N_HIDDEN:], 50)) & (scene.opacity_logit > 1.0))
    assert len(opaque) > 20
    assert c[opaque].min() > hidden.max()
    assert np.median(c[opaque]) > 0.5


def test_deterministic_in_the_seed():
    scene, cams = _scene(80), _cams()
    params = {"train_longest_side": 24, "iterations": 12}
    spec = get_pruner("confsplat")
    a = spec.score(scene, PruneContext(params=params, seed=3, cameras=cams))
    b = spec.score(scene, PruneContext(params=params, seed=3, cameras=cams))
    np.testing.assert_array_equal(a, b)
    r3 = optimise_confidence(scene, cams, params, seed=3)
    r4 = optimise_confidence(scene, cams, params, seed=4)
    np.testing.assert_array_equal(r3.confidence, a)
    assert r3.views != r4.views and not np.array_equal(r3.confidence, r4.confidence)
    assert sorted(r3.views[:4]) == [0, 1, 2, 3]  # every view once per epoch


def test_bad_parameters_and_missing_cameras():
    scene = _scene(20)
    with pytest.raises(ValueError, match="entropy_sign"):
        optimise_confidence(scene, _cams(), {"entropy_sign": "up", "iterations": 1})
    with pytest.raises(RuntimeError, match="needs cameras"):
        get_pruner("confsplat").score(scene, PruneContext())


def test_matmul_blur_equals_the_metric_blur():
    from harness.metrics.ssim import blur_torch, gaussian_taps
    from methods.confsplat.train import blur_matmul

    x = torch.rand(1, 5, 23, 41, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    np.testing.assert_allclose(blur_matmul(x, gaussian_taps()).numpy(), blur_torch(x, gaussian_taps()).numpy(),
                               rtol=0, atol=1e-14)


def test_confidences_do_not_depend_on_the_thread_count():
    """Beyond torch's parallel grain (32,768 elements) its CPU softplus, lgamma/digamma/polygamma and
    sums round the elements at each thread's chunk boundary differently, so a training loop run on
    more threads learned other confidences; the loop runs on one thread whatever ``threads`` says
    (``threads: 0``, the worker's own count, included)."""
    scene = random_scene(40_062, sh_degree=0, seed=2)  # two threads: chunks of 20,031, ends off the vector grid
    scene.scales_log[:] += 1.0
    params = {"train_longest_side": 32, "iterations": 3}
    before = torch.get_num_threads()
    try:
        runs = []
        for threads, process in ((1, 1), (2, 2), (0, 2)):
            torch.set_num_threads(process)
            runs.append(optimise_confidence(scene, _cams()[:2], {**params, "threads": threads}, seed=0).confidence)
            assert torch.get_num_threads() == process  # the process's own count comes back
    finally:
        torch.set_num_threads(before)
    assert len(np.unique(runs[0])) > 100  # the views see many splats: the check has something to compare
    np.testing.assert_array_equal(runs[0], runs[1])
    np.testing.assert_array_equal(runs[0], runs[2])
