"""``betadesc-vr``: the virtual-rig significance as retention evidence in BetaDescPrune's Beta model."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import spearmanr

from methods import PruneContext, get_pruner
from methods.betadesc.vr import normalise
from methods.virtualrig import VirtualRigParams, virtual_significance
from tests.test_virtualrig import _small_object

RIG = {"views": 6, "resolution": 32}


def test_normalise_rank_and_log_minmax():
    x = np.array([0.0, 0.0, 1.0, 10.0, 100.0])
    np.testing.assert_allclose(normalise(x, "rank"), [0.125, 0.125, 0.5, 0.75, 1.0])  # ties averaged
    y = np.log1p(x / 10.0)  # median of the positive values: 10
    np.testing.assert_allclose(normalise(x, "log-minmax"), y / y.max())
    np.testing.assert_array_equal(normalise(np.full(4, 3.0), "rank"), np.zeros(4))
    with pytest.raises(ValueError, match="unknown vr_norm"):
        normalise(x, "z")


@pytest.mark.parametrize("descriptors", [True, False])
def test_zero_weight_is_betadesc_and_its_ablation(descriptors):
    """vr_weight 0 adds nothing: the score is betadesc's (descriptors) or betadesc-nodesc's, same reading
    (betadesc-vr's own default reading, round-two: the one its selection was made on)."""
    scene = _small_object()
    got = get_pruner("betadesc-vr").score(scene, PruneContext(params={**RIG, "vr_weight": 0.0,
                                                                      "descriptors": descriptors}))
    same = {"reading": "round-two"}
    base = get_pruner("betadesc" if descriptors else "betadesc-nodesc").score(scene, PruneContext(params=same))
    np.testing.assert_allclose(got, base, rtol=1e-12)


def test_evidence_adds_the_normalised_significance_to_a():
    """With descriptors off and opacity-only statistics, A and B are known in closed form, so the
    score is checked against the Beta mean + γσ computed here."""
    scene = _small_object()
    p = {**RIG, "vr_weight": 2.0, "descriptors": False, "nodesc_def": "opacity-only"}
    got = get_pruner("betadesc-vr").score(scene, PruneContext(params=p))
    g = normalise(virtual_significance(scene, VirtualRigParams.parse(RIG)), "rank")
    o = 1.0 / (1.0 + np.exp(-scene.opacity_logit.astype(np.float64)))
    o = (o - o.min()) / np.ptp(o)  # o_norm minmax (default reading)
    a = 1.0 + 0.55 * o + 2.0 * g
    b = 1.0 + 0.20 * (1.0 - o)
    mean, var = a / (a + b), a * b / ((a + b) ** 2 * (a + b + 1.0))
    np.testing.assert_allclose(got, mean + 0.25 * np.sqrt(var), rtol=1e-7)  # opacity in float32


def test_a_large_weight_ranks_by_the_significance_over_the_pruning_evidence():
    """The significance does not take over the ranking as the weight grows: with A = A0 + w·g → ∞,
    μ + γσ = 1 − (B − γ√B)/A + O(A⁻²), so the score ranks by g / (B − γ√B) — the Beta model's pruning
    evidence B keeps dividing it (with the default reading, g alone reaches only ρ ≈ 0.93 here)."""
    from methods.betadesc import pipeline

    scene = _small_object()
    params = get_pruner("betadesc-vr").parse_params({**RIG, "vr_weight": 1e6})
    g = normalise(virtual_significance(scene, VirtualRigParams.parse(RIG)), "rank")
    got = get_pruner("betadesc-vr").score(scene, PruneContext(params=params.to_dict()))
    b = pipeline.components(scene, params, None, descriptors=True).b
    assert spearmanr(got, g / (b - params.gamma * np.sqrt(b))).statistic > 0.999


def test_registered_camera_free():
    spec = get_pruner("betadesc-vr")
    assert spec.group == "camera-free" and not spec.needs and spec.ablation is None
    assert {"views", "resolution", "vr_weight", "reading", "voxel"} <= set(spec.params.names())
