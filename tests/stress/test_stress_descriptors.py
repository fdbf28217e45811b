"""BetaDescPrune and its ablations on degenerate clouds, through the registry (the pruner contract).

Cases: exact duplicates, collinear and coplanar clouds, a single splat, fewer splats than the
neighbourhood (max_nn), coordinates offset by 1e6, scales from 1e-8 to 1e4, zero opacity, SH with
huge coefficients, and random mixtures of all of these (Hypothesis). Every pruner must return finite
float64 scores of the right length (the registry checks shape and finiteness and raises otherwise),
Beta scores within [0, 1 + γ/2], and ratio targeting on them must remove exactly round(r·N) splats.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from harness.core.scene import SH_REST_COUNT, GaussianScene
from methods.registry import PruneContext, get_pruner
from methods.targeting import select_by_ratio
from tests.stress.budget import examples

pytestmark = pytest.mark.stress

PRUNERS = ("betadesc", "betadesc-nodesc", "betadesc-nobeta", "betadesc-nodesc-nobeta")
BETA = {"betadesc", "betadesc-nodesc"}


def _scene(means, *, scales_log=None, opacity_logit=None, sh_dc=None, sh_rest=None, degree=1, seed=0):
    rng = np.random.default_rng(seed)
    n = len(means)
    k = SH_REST_COUNT[degree]
    return GaussianScene.from_arrays(
        means=means,
        scales_log=rng.normal(-4.0, 0.5, (n, 3)) if scales_log is None else scales_log,
        quats=rng.normal(size=(n, 4)) + np.array([3.0, 0, 0, 0]),
        opacity_logit=rng.normal(0, 2, n) if opacity_logit is None else opacity_logit,
        sh_dc=rng.normal(size=(n, 3)) if sh_dc is None else sh_dc,
        sh_rest=rng.normal(0, 0.1, (n, k, 3)) if sh_rest is None else sh_rest,
    )


def _cloud(n=400, seed=0):
    return np.random.default_rng(seed).normal(size=(n, 3))


def _cases() -> dict[str, GaussianScene]:
    rng = np.random.default_rng(1)
    t = np.linspace(-1, 1, 300)
    n = 400
    return {
        "duplicates": _scene(np.repeat(_cloud(20), 20, axis=0)),
        "one-point": _scene(np.zeros((50, 3))),
        "collinear": _scene(np.stack([t, 2 * t, -t], 1)),
        "coplanar": _scene(np.c_[rng.uniform(-1, 1, (n, 2)), np.zeros(n)]),
        "single": _scene(np.array([[0.1, 0.2, 0.3]])),
        "two": _scene(np.array([[0.0, 0, 0], [1.0, 0, 0]])),
        "fewer-than-nn": _scene(_cloud(7)),
        "offset-1e6": _scene(_cloud(n) * 100.0 + 1e6),
        "tiny-scales": _scene(_cloud(n), scales_log=np.full((n, 3), np.log(1e-8))),
        "huge-scales": _scene(_cloud(n), scales_log=np.full((n, 3), np.log(1e4))),
        "scales-1e-8-to-1e4": _scene(_cloud(n), scales_log=rng.uniform(np.log(1e-8), np.log(1e4), (n, 3))),
        "zero-opacity": _scene(_cloud(n), opacity_logit=np.full(n, -1e4)),
        "full-opacity": _scene(_cloud(n), opacity_logit=np.full(n, 1e4)),
        "huge-sh": _scene(_cloud(n), sh_dc=rng.normal(0, 1e18, (n, 3)), sh_rest=rng.normal(0, 1e18, (n, 3, 3))),
        "max-sh": _scene(_cloud(n), sh_dc=np.full((n, 3), 3e38), sh_rest=np.full((n, 3, 3), -3e38)),
        "sh-degree-3": _scene(_cloud(n), degree=3),
        "tiny-extent": _scene(_cloud(n) * 1e-7),
    }


CASES = _cases()


def _check(scene: GaussianScene, name: str, params: dict | None = None) -> np.ndarray:
    spec = get_pruner(name)
    scores = spec.score(scene, PruneContext(params=params or {}))  # raises on non-finite / wrong shape
    assert scores.dtype == np.float64 and scores.shape == (len(scene),)
    if name in BETA:
        assert (scores >= 0).all() and (scores <= 1.125 + 1e-12).all()
    for r in (0.1, 0.5):
        sel = select_by_ratio(scores, r)
        assert int((~sel.keep).sum()) == round(r * len(scene))
    return scores


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("pruner", PRUNERS)
def test_degenerate_clouds(stress_counts, case, pruner):
    stress_counts.add("descriptors", named=1)
    _check(CASES[case], pruner)


@pytest.mark.parametrize("pruner", ("betadesc", "betadesc-nobeta"))
@pytest.mark.parametrize("params", [{"voxel": 1e-6}, {"voxel": 0.5}, {"max_nn": 1}, {"radius_voxels": 0.01},
                                    {"colour_bins": 1}])
def test_extreme_descriptor_parameters(stress_counts, pruner, params):
    stress_counts.add("descriptors", parameters=1)
    for case in ("duplicates", "coplanar", "offset-1e6", "single"):
        _check(CASES[case], pruner, params)


def test_duplicated_splats_score_alike(stress_counts):
    """Exact copies of a splat (same position and attributes) get the same score: the descriptor
    neighbourhood of identical points is identical."""
    base = _scene(_cloud(60, seed=3), seed=3)
    idx = np.repeat(np.arange(60), 3)
    scene = base.subset(idx)
    stress_counts.add("descriptors", duplicates=len(PRUNERS))
    for name in PRUNERS:
        s = _check(scene, name).reshape(60, 3)
        np.testing.assert_allclose(s, s[:, :1].repeat(3, 1), rtol=0, atol=1e-12, err_msg=name)


_pathology = st.sampled_from(["none", "duplicate", "plane", "line", "offset", "tiny", "huge", "zero-o", "big-sh"])


@examples(6, 400)
@given(st.integers(1, 300), st.lists(_pathology, min_size=1, max_size=4), st.integers(0, 2**31 - 1),
       st.sampled_from(PRUNERS))
def test_random_mixtures(stress_counts, n, pathologies, seed, pruner):
    rng = np.random.default_rng(seed)
    means = rng.normal(size=(n, 3))
    scales = rng.normal(-4, 0.5, (n, 3))
    opac = rng.normal(0, 2, n)
    dc = rng.normal(size=(n, 3))
    for p in pathologies:
        pick = rng.random(n) < 0.5
        if p == "duplicate":
            means[pick] = means[0]
        elif p == "plane":
            means[pick, 2] = 0.0
        elif p == "line":
            means[pick] = np.outer(rng.uniform(-1, 1, pick.sum()), [1.0, 2.0, 3.0])
        elif p == "offset":
            means += 1e6
        elif p == "tiny":
            scales[pick] = np.log(1e-8)
        elif p == "huge":
            scales[pick] = np.log(1e4)
        elif p == "zero-o":
            opac[pick] = -1e4
        elif p == "big-sh":
            dc[pick] = 1e20
    stress_counts.add("descriptors", random=1)
    _check(_scene(means, scales_log=scales, opacity_logit=opac, sh_dc=dc, seed=seed), pruner)
