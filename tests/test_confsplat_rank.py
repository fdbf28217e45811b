"""ConfSplat's saliency rank loss: hinge gradient direction, the colour gradient its saliency is built
on, its effect on a tiny scene, and the time budget that no longer cuts runs silently."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from methods import get_pruner
from methods.confsplat.train import (
    beta_gate,
    image_loss,
    optimise_confidence,
    prepare_views,
    rank_loss,
    rank_pairs,
    view_saliency,
)
from methods.lightgs.significance import significance
from renderers.pixel_pairs import composite, render_pairs
from tests.test_confsplat import N_HIDDEN, _cams, _scene


def test_rank_pairs_sorted_with_lowest_index_ties():
    s = torch.tensor([3.0, 0.0, 5.0, 0.0, 3.0, 0.0])
    hi, lo = rank_pairs(s, 3)
    assert hi.tolist() == [2, 0, 4] and lo.tolist() == [1, 3, 5]
    assert rank_pairs(s, 99)[0].numel() == 6  # capped at N


def test_rank_loss_gradient_direction_by_hand():
    c = torch.tensor([0.5, 0.5, 0.5, 0.5, 0.5, 0.5], requires_grad=True)
    sal = torch.tensor([5.0, 4.0, 3.0, 2.0, 1.0, 0.0])
    loss = rank_loss(c, sal, 2, 1.0)  # pairs (0, 5) and (1, 4), both active
    assert float(loss.detach()) == pytest.approx(1.0)
    loss.backward()
    # gradient descent raises the most salient and lowers the least salient
    np.testing.assert_allclose(c.grad.numpy(), [-0.5, -0.5, 0, 0, 0.5, 0.5])
    # HEAD's margin 0.1: a pair already separated by more than the margin is inactive
    c2 = torch.tensor([0.9, 0.5, 0.5, 0.5, 0.45, 0.1], requires_grad=True)
    rank_loss(c2, sal, 2, 0.1).backward()  # pair (0, 5): 0.1 + 0.1 − 0.9 < 0; pair (1, 4): 0.1 + 0.45 − 0.5 > 0
    np.testing.assert_allclose(c2.grad.numpy(), [0, -0.5, 0, 0, 0.5, 0])
    # when every splat is in both halves (N <= K) and the hinge is always active, the pushes cancel
    c3 = torch.full((6,), 0.5, requires_grad=True)
    rank_loss(c3, sal, 6, 1.0).backward()
    np.testing.assert_array_equal(c3.grad.numpy(), 0.0)


def test_colour_gradient_of_the_pair_render_is_exact():
    scene, cams = _scene(60, seed=2), _cams()
    v = prepare_views(scene, cams[:1], 0)[0]
    w = torch.rand(v.target.shape, generator=torch.Generator().manual_seed(0))
    colors = v.colors.clone().requires_grad_(True)
    (render_pairs(v.pairs, v.base, colors=colors) * w).sum().backward()
    # the image is linear in the colours: a unit change of colour (j, ch) moves Σ w·img by the gradient
    base = float((torch.from_numpy(composite(v.pairs).image) * w).sum())
    for j, ch in [(0, 0), (len(v.ids) // 2, 1), (len(v.ids) - 1, 2)]:
        bumped = v.pairs.colors.copy()
        bumped[j, ch] += 1.0
        moved = float((torch.from_numpy(composite(v.pairs, colors=bumped).image) * w).sum())
        assert moved - base == pytest.approx(float(colors.grad[j, ch]), rel=1e-4, abs=1e-4)
    np.testing.assert_array_equal(render_pairs(v.pairs, v.base).numpy(), composite(v.pairs).image)


def test_rank_gradient_on_a_tiny_scene_raises_salient_and_lowers_unseen_splats():
    scene, cams = _scene(), _cams()
    n = len(scene)
    a = torch.ones(n, requires_grad=True)
    b = torch.ones(n, requires_grad=True)
    sal = torch.zeros(n, dtype=torch.float64)
    for v in prepare_views(scene, cams, 0):  # one image-loss backward per view, as training accumulates
        colors = v.colors.clone().requires_grad_(True)
        c = beta_gate(a, b)[0]
        image_loss(render_pairs(v.pairs, v.base * c[v.ids], colors=colors), v.target, 0.2).backward()
        sal.index_add_(0, v.ids, view_saliency(v, colors.grad).double())
    assert (sal[:N_HIDDEN] == 0).all() and (sal[N_HIDDEN:] > 0).sum() > 100  # unseen splats: no saliency
    hi, lo = rank_pairs(sal, 20)
    assert set(range(N_HIDDEN)) <= set(lo.tolist())  # zero saliency, lowest indices: least salient
    sig = significance(scene, cams, longest_side=0, early_stop=False)
    assert np.corrcoef(sal.numpy(), sig)[0, 1] > 0.5  # saliency tracks what the images need
    a.grad = b.grad = None
    rank_loss(beta_gate(a, b)[0], sal, 20, 1.0).backward()
    ga, gb = a.grad.numpy(), b.grad.numpy()
    # a descent step raises α (lowers β) of the most salient, the reverse for the least salient
    assert (ga[hi] < 0).all() and (gb[hi] > 0).all() and (ga[lo] > 0).all() and (gb[lo] < 0).all()
    rest = np.setdiff1d(np.arange(n), np.r_[hi, lo])
    assert (ga[rest] == 0).all() and (gb[rest] == 0).all()


def test_rank_steps_in_training_and_the_adam_damping_of_unseen_splats():
    scene, cams = _scene(), _cams()
    common = {"train_longest_side": 0, "iterations": 76, "rank_pairs": 20, "rank_margin": 1.0}
    on = optimise_confidence(scene, cams, common, seed=1)
    off = optimise_confidence(scene, cams, {**common, "rank_weight": 0.0}, seed=1)
    assert on.rank_steps == 3 and off.rank_steps == 0  # steps 25, 50, 75 (step 0: empty buffer)
    assert on.rank_losses[0] == pytest.approx(1.0, abs=0.05)  # c ≈ ½ on both sides at first
    assert not np.array_equal(on.confidence, off.confidence)
    # documented Adam effect (train.py docstring): the rank spikes inflate the second moment of the
    # unseen splats, whose only other gradient is the regularisers', so they fall less far
    assert (on.confidence[:N_HIDDEN] > off.confidence[:N_HIDDEN]).all()
    assert (on.confidence[:N_HIDDEN] < 0.5).all()


def test_rank_loss_is_a_no_op_when_every_splat_is_in_both_halves():
    scene, cams = _scene(), _cams()  # 150 splats <= 2048 pairs, margin 1.0: the pushes cancel exactly
    common = {"train_longest_side": 24, "iterations": 60}
    on = optimise_confidence(scene, cams, common, seed=2)
    off = optimise_confidence(scene, cams, {**common, "rank_weight": 0.0}, seed=2)
    assert on.rank_steps == 2
    np.testing.assert_array_equal(on.confidence, off.confidence)


def test_no_time_budget_by_default_and_a_binding_budget_is_recorded():
    params = get_pruner("confsplat").parse_params()
    assert params.time_budget_s is None and params.iterations >= 600
    assert (params.rank_weight, params.rank_interval, params.rank_pairs, params.rank_margin,
            params.rank_start_step) == (1.0, 25, 2048, 1.0, 0)
    scene, cams = _scene(40), _cams()
    full = optimise_confidence(scene, cams, {"train_longest_side": 16, "iterations": 5}, seed=0)
    assert full.iterations == 5 and not full.stopped_by_budget
    cut = optimise_confidence(scene, cams, {"train_longest_side": 16, "iterations": 10**6,
                                            "time_budget_s": 1e-9}, seed=0)
    assert cut.stopped_by_budget and cut.iterations == 1
