"""`harness diagnose`: render-free numbers checked by hand on a tiny scene, and end to end on grape-small."""

from __future__ import annotations

import json

import numpy as np
import pytest

from harness.cli import main
from harness.core.scene import GaussianScene
from methods import diagnose as dg
from tests.scene_factory import random_scene


def _tiny() -> GaussianScene:
    """Five splats clustered in one voxel near the origin and five alone in far corners; opacity
    logits 0 (o = ½), scales_log 0 (V = 1) except splat 9 (V = e³); opacity rises with the index."""
    cluster = np.array([[0.0, 0, 0], [1e-3, 0, 0], [0, 1e-3, 0], [0, 0, 1e-3], [1e-3, 1e-3, 0]])
    far = np.array([[10.0, 0, 0], [0, 10, 0], [0, 0, 10], [10, 10, 0], [10, 10, 10]])
    scales = np.zeros((10, 3))
    scales[9] = 1.0
    return GaussianScene.from_arrays(np.r_[cluster, far], scales, np.tile([1.0, 0, 0, 0], (10, 1)),
                                     np.linspace(-2, 2, 10), np.zeros((10, 3)))


def test_removal_shares_by_hand():
    scene = _tiny()
    sig = np.arange(1.0, 11.0)  # Σ = 55
    removed = np.r_[np.ones(5, bool), np.zeros(5, bool)]  # the whole cluster
    r = dg.removal(scene, removed, sig, voxel=0.01)
    assert r["significance_removed"] == pytest.approx(15 / 55)
    o = 1 / (1 + np.exp(-np.linspace(-2, 2, 10)))
    v = np.r_[np.ones(9), np.exp(3.0)]
    assert r["opacity_volume_removed"] == pytest.approx((o[:5] * v[:5]).sum() / (o * v).sum())
    assert r["region_removed"] == 1.0 and r["voxels_emptied"] == pytest.approx(1 / 6)
    # thinning: one splat of the cluster and one far splat; the far one empties its voxel
    thin = np.zeros(10, bool)
    thin[[0, 5]] = True
    r2 = dg.removal(scene, thin, sig, voxel=0.01)
    assert r2["significance_removed"] == pytest.approx(7 / 55)
    assert r2["region_removed"] == 0.5 and r2["voxels_emptied"] == pytest.approx(1 / 6)
    assert dg.removal(scene, np.zeros(10, bool), sig)["region_removed"] == 0.0


def test_spearman_and_diagnose_for_a_simple_pruner():
    scene = _tiny()
    sig = np.arange(1.0, 11.0)
    assert dg.spearman(sig, sig) == pytest.approx(1.0) and dg.spearman(np.ones(10), sig) is None
    d = dg.diagnose(scene, "opacity", {}, 0.5, sig)  # opacity rises with the index: removes 0..4
    assert d.removed == 5 and d.correlations == {"score": pytest.approx(1.0)}
    assert d.significance_removed == pytest.approx(15 / 55) and d.region_removed == 1.0
    rev = dg.diagnose(scene, "opacity", {}, 0.5, sig[::-1].copy())
    assert rev.correlations["score"] == pytest.approx(-1.0) and rev.significance_removed == pytest.approx(40 / 55)


def test_betadesc_components_are_reported_and_agree_with_the_pruner():
    from methods import PruneContext, get_pruner

    scene = random_scene(600, sh_degree=1, seed=3)
    params = {"voxel": 0.05, "radius_voxels": 3.0, "max_nn": 40}
    q = dg.quantities(scene, "betadesc", params)
    assert set(q) == {"s", "ell", "o", "u", "w", "A", "B", "score"}
    np.testing.assert_array_equal(q["score"], get_pruner("betadesc").score(scene, PruneContext(params=params)))
    sig = q["o"] * 3 + 1  # significance = a monotone function of o
    d = dg.diagnose(scene, "betadesc", params, 0.3, sig)
    assert d.correlations["o"] == pytest.approx(1.0)
    assert set(d.correlations) == set(q) and d.removed == 180


@pytest.mark.data
def test_diagnose_cli_on_grape_small(capsys):
    from harness.io import datasets

    if not datasets.scene_path("grape-small").exists():
        pytest.skip("grape-small not available (../shared/data)")
    assert main(["diagnose", "grape-small", "--ratio", "0.3", "--n-train", "4", "--significance-side", "128",
                 "--method", "betadesc:reading=v1", "--method", "betadesc:reading=paper-literal", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    by = {d["label"]: d for d in out["diagnoses"]}
    assert set(by) == {"betadesc:reading=v1", "betadesc:reading=paper-literal", "random", "opacity", "lightgs"}
    assert out["splats"] == 5000 and out["train_views"] == 4
    for d in by.values():
        assert d["removed"] == 1500
        assert 0 <= d["significance_removed"] <= 1 and 0 <= d["region_removed"] <= 1
    # random removes about its share; lightgs removes the least significance by construction
    assert abs(by["random"]["opacity_volume_removed"] - 0.3) < 0.1
    assert by["lightgs"]["significance_removed"] == min(d["significance_removed"] for d in by.values())
    assert by["lightgs"]["correlations"]["score"] == pytest.approx(1.0)
    assert set(by["betadesc:reading=v1"]["correlations"]) == {"s", "ell", "o", "u", "w", "A", "B", "score"}
    assert main(["diagnose", "grape-small", "--method", "betadesc:o_norm=bad"]) == 2


def test_spearman_is_scipys_without_importing_it():
    from scipy import stats

    from methods.diagnose import average_ranks, spearman

    rng = np.random.default_rng(0)
    for t in range(60):
        n = int(rng.integers(2, 2000))
        x = rng.integers(0, 5, n).astype(float) if t % 2 else rng.normal(size=n)  # ties, or none
        y = x * rng.normal() + rng.normal(size=n)
        assert np.array_equal(average_ranks(x), stats.rankdata(x))
        if np.ptp(x) > 0 and np.ptp(y) > 0:
            assert spearman(x, y) == pytest.approx(stats.spearmanr(x, y)[0], abs=1e-12)
    assert spearman(np.ones(5), np.arange(5.0)) is None
