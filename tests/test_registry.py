"""Pruner registry, shared ratio targeting and the simple baselines."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from harness.cli import main
from harness.core.params import ParamError
from methods import (
    PruneContext,
    get_pruner,
    list_pruners,
    register_pruner,
    select_by_keep,
    select_by_ratio,
)
from methods.targeting import removal_count
from tests.scene_factory import random_scene


def test_simple_baselines_registered_and_documented():
    names = {s.name for s in list_pruners()}
    assert {"opacity", "volume", "random"} <= names
    for s in list_pruners():
        assert s.summary and s.summary != s.name


def test_opacity_and_volume_scores_match_hand_computation():
    scene = random_scene(50, seed=3)
    o = 1 / (1 + np.exp(-scene.opacity_logit.astype(np.float64)))
    np.testing.assert_allclose(get_pruner("opacity").score(scene, PruneContext()), o, rtol=1e-12)
    vol = np.exp(scene.scales_log.astype(np.float64)).prod(1) * o
    got = get_pruner("volume").score(scene, PruneContext())
    assert (np.argsort(got, kind="stable") == np.argsort(vol, kind="stable")).all()


def test_volume_score_finite_for_extreme_scales():
    scene = random_scene(4, seed=1)
    scene.scales_log[:] = [[-80, -80, -80], [80, 80, 80], [0, 0, 0], [-1, 2, 3]]
    scene.opacity_logit[:] = [-200, 200, 0, 5]
    s = get_pruner("volume").score(scene, PruneContext())
    assert np.isfinite(s).all() and s[1] > s[2] > s[0]


def test_random_is_seeded():
    scene = random_scene(100)
    a = get_pruner("random").score(scene, PruneContext(seed=1))
    b = get_pruner("random").score(scene, PruneContext(seed=1))
    c = get_pruner("random").score(scene, PruneContext(seed=2))
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_unknown_parameter_and_pruner_rejected():
    with pytest.raises(ParamError, match="gamma: no such parameter"):
        get_pruner("opacity").score(random_scene(3), PruneContext(params={"gamma": 1}))
    with pytest.raises(KeyError, match="unknown pruner"):
        get_pruner("no-such-pruner")


def test_needs_are_enforced():
    @register_pruner("_test-needs-cams", needs=("cameras",))
    def _fn(scene, ctx):
        """Test pruner needing cameras."""
        return np.zeros(len(scene))

    spec = get_pruner("_test-needs-cams")
    assert spec.missing_needs(PruneContext()) == ["cameras"]
    with pytest.raises(RuntimeError, match="needs cameras"):
        spec.score(random_scene(3), PruneContext())
    assert spec.missing_needs(PruneContext(cameras=[object()])) == []


@pytest.mark.parametrize("ratio", [0.0, 0.1, 0.3, 0.5, 0.7, 1.0])
@pytest.mark.parametrize("n", [0, 1, 7, 10, 1001])
def test_exact_prune_counts(ratio, n):
    scores = np.random.default_rng(n).random(n)
    sel = select_by_ratio(scores, ratio)
    assert sel.removed == round(ratio * n) == n - sel.kept
    if sel.removed and sel.kept:
        assert scores[~sel.keep].max() <= scores[sel.keep].min()
        assert sel.tau == scores[~sel.keep].max()
    keep = select_by_keep(scores, 1 - ratio)
    assert keep.removed == removal_count(n, 1 - (1 - ratio))


def test_ties_broken_by_index():
    sel = select_by_ratio(np.array([1.0, 0.5, 0.5, 0.5, 2.0]), 0.4)  # remove 2 of the three ties
    assert sel.keep.tolist() == [True, False, False, True, True]
    assert sel.tau == 0.5


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-1e6, 1e6), min_size=1, max_size=200), st.floats(0, 1))
def test_removal_is_lowest_scores(values, ratio):
    scores = np.array(values)
    sel = select_by_ratio(scores, ratio)
    assert sel.removed == round(ratio * len(scores))
    # the removed set is exactly the first k of a stable (score, index) sort
    order = np.lexsort((np.arange(len(scores)), scores))
    assert set(np.flatnonzero(~sel.keep)) == set(order[: sel.removed].tolist())


def test_methods_command_lists_json(capsys):
    assert main(["methods", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    by_name = {r["name"]: r for r in rows}
    assert by_name["random"]["params"] == {} and by_name["random"]["group"] == "baseline"
    assert by_name["opacity"]["needs"] == [] and by_name["lightgs"]["needs"] == ["cameras"]
    voxel = by_name["betadesc"]["params"]["voxel"]
    assert voxel["type"] == "float > 0, <= 1" and voxel["default"] == 0.01
    assert voxel["doc"].startswith("voxel edge as a fraction of the bounding-box diagonal")
    assert by_name["betadesc"]["ablation"] == {"descriptors": True, "beta": True}


def test_third_party_pruner_through_an_entry_point(tmp_path, monkeypatch):
    """A package names a module under the `harness.pruners` entry-point group; asking the registry
    for an unknown name loads it, and its pruner (with typed params and metadata) is usable."""
    from methods.registry import PRUNERS

    (tmp_path / "plugin_pruners.py").write_text(
        "from dataclasses import dataclass\n"
        "import numpy as np\n"
        "from harness.core.params import Params, param\n"
        "from methods.registry import register_pruner\n\n"
        "@dataclass(frozen=True)\n"
        "class P(Params):\n"
        "    sign: float = param(1.0, doc='multiplies the x coordinate')\n\n"
        "@register_pruner('plugin-x', params=P, label='Plugin X')\n"
        "def score(scene, ctx):\n"
        "    '''Keep large x.'''\n"
        "    return ctx.params.sign * scene.means[:, 0].astype(np.float64)\n")
    dist = tmp_path / "plugin_pruners-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: plugin-pruners\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[harness.pruners]\nplugin = plugin_pruners\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("HARNESS_PLUGINS", "plugin-pruners")  # this test's plugin, whatever else is installed
    monkeypatch.setattr(PRUNERS, "_plugins_loaded", False)
    monkeypatch.setattr(PRUNERS, "_entries", dict(PRUNERS._entries))
    spec = get_pruner("plugin-x")
    assert spec.label == "Plugin X" and spec.group == "other" and spec.params.names() == ("sign",)
    scene = random_scene(20, seed=4)
    np.testing.assert_array_equal(spec.score(scene, PruneContext(params={"sign": -1.0})), -scene.means[:, 0])
    with pytest.raises(ParamError, match="sign: expected a number"):
        spec.parse_params({"sign": "x"})
