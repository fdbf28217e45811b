"""The four registered BetaDescPrune pruners: contract, determinism, invariances, degenerate scenes."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from harness.core.cameras import Camera
from harness.core.scene import GaussianScene
from methods import PruneContext, get_pruner, select_by_ratio
from tests.scene_factory import random_scene

NAMES = ("betadesc", "betadesc-nodesc", "betadesc-nobeta", "betadesc-nodesc-nobeta")
REPO = Path(__file__).resolve().parent.parent
RATIOS = (0.0, 0.1, 0.3, 0.7, 1.0)
# small voxels relative to these tiny scenes so that neighbourhoods hold several voxels
SMALL = {"voxel": 0.05, "radius_voxels": 3.0, "max_nn": 40}


def _score(name: str, scene: GaussianScene, **params) -> np.ndarray:
    spec = get_pruner(name)
    if "voxel" in spec.params.names():
        params = {**SMALL, **params}
    return spec.score(scene, PruneContext(params=params))


def _with_means(scene: GaussianScene, means, scales_log=None) -> GaussianScene:
    return GaussianScene.from_arrays(
        means, scene.scales_log if scales_log is None else scales_log, scene.quats,
        scene.opacity_logit, scene.sh_dc, scene.sh_rest)


def test_registered_with_documented_params():
    for name in NAMES:
        spec = get_pruner(name)
        assert not spec.needs and spec.summary != name
        assert {"preset", "view_weight"} <= set(spec.params.names())
        assert all(p.doc for p in spec.params.specs())
    full = get_pruner("betadesc").parse_params()
    assert full.voxel == 0.01 and full.gamma == 0.25 and full.score == "ucb"  # the paper's L313 and L315
    assert full.view_weight == 0.0  # camera-agnostic unless asked
    assert "score" not in get_pruner("betadesc-nobeta").params.names()
    assert "voxel" not in get_pruner("betadesc-nodesc").params.names()


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("degree", [0, 3])
def test_scores_finite_float64_and_repeatable(name, degree):
    scene = random_scene(600, sh_degree=degree, seed=11)
    a = _score(name, scene)
    b = _score(name, scene)
    assert a.dtype == np.float64 and a.shape == (600,) and np.isfinite(a).all()
    np.testing.assert_array_equal(a, b)
    assert len(np.unique(a)) > 300  # a ranking, not a handful of ties


@pytest.mark.parametrize("kind", ["ucb", "lcb", "quantile", "literal"])
def test_every_score_kind_runs_and_literal_reverses_lcb(kind):
    scene = random_scene(500, sh_degree=1, seed=12)
    s = _score("betadesc", scene, score=kind)
    assert np.isfinite(s).all()
    if kind == "literal":
        lcb = _score("betadesc", scene, score="lcb", z=0.25)
        np.testing.assert_allclose(s, 1.0 - lcb, atol=1e-12)


def test_presets_change_the_ranking_but_stay_close():
    scene = random_scene(800, seed=13)
    base = _score("betadesc", scene)
    for p in ("flat", "opacity-heavy", "structure-heavy"):
        other = _score("betadesc", scene, preset=p)
        assert not np.array_equal(base, other)
        assert np.corrcoef(base, other)[0, 1] > 0.5


_THREAD_SCRIPT = """
import hashlib, sys
import numpy as np
sys.path.insert(0, {repo!r})
from tests.scene_factory import random_scene
from methods import PruneContext, get_pruner
scene = random_scene(4000, sh_degree=3, seed=14)
for name in {names!r}:
    own = {params!r} if name in ("betadesc", "betadesc-nobeta") else {{}}
    s = get_pruner(name).score(scene, PruneContext(params=own))
    print(name, hashlib.sha256(s.tobytes()).hexdigest())
"""


def test_bit_identical_across_thread_counts():
    script = _THREAD_SCRIPT.format(repo=str(REPO), names=NAMES, params=SMALL)
    outputs = []
    for threads in ("1", "2"):
        env = {**os.environ, **{k: threads for k in (
            "OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
            "TORCH_NUM_THREADS")}}
        run = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True,
                             timeout=600, cwd=REPO, check=False)
        assert run.returncode == 0, run.stderr
        outputs.append(run.stdout)
    assert outputs[0] == outputs[1] and len(outputs[0].splitlines()) == 4


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(1, 80), seed=st.integers(0, 2**16), degree=st.sampled_from([0, 1, 3]),
       dup=st.booleans(), name=st.sampled_from(NAMES), data=st.data())
def test_permuting_splats_permutes_scores(n, seed, degree, dup, name, data):
    scene = random_scene(n, sh_degree=degree, seed=seed)
    if dup:  # duplicated rows: identical splats in several places
        scene = scene.subset(np.random.default_rng(seed).integers(0, n, n + 5))
    perm = np.array(data.draw(st.permutations(range(len(scene)))), dtype=np.int64)
    base = _score(name, scene)
    np.testing.assert_array_equal(_score(name, scene.subset(perm)), base[perm])


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**16), name=st.sampled_from(NAMES))
def test_translation_by_1e6_changes_nothing(seed, name):
    # positions on a 1/16 grid within ±1000: x + 1e6 is exact in float32, so the relative
    # geometry is identical and the scores must be bit-identical
    scene = random_scene(300, sh_degree=1, seed=seed)
    means = np.round(scene.means.astype(np.float64) * 200 * 16) / 16
    base = _with_means(scene, means)
    moved = _with_means(scene, means + 1e6)
    np.testing.assert_array_equal(moved.means.astype(np.float64) - 1e6, means)
    np.testing.assert_array_equal(_score(name, moved), _score(name, base))


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("factor", [1e-3, 1e3])
@pytest.mark.parametrize("seed", [15, 16])
def test_scaling_changes_no_decision(name, factor, seed):
    scene = random_scene(700, sh_degree=2, seed=seed)
    scaled = _with_means(scene, scene.means.astype(np.float64) * factor,
                         scene.scales_log.astype(np.float64) + np.log(factor))
    a, b = _score(name, scene), _score(name, scaled)
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-5)
    for r in RATIOS:
        np.testing.assert_array_equal(select_by_ratio(a, r).keep, select_by_ratio(b, r).keep)


def _degenerate_scenes():
    base = random_scene(40, sh_degree=3, seed=17)
    t = np.linspace(0, 1, 40)
    zero_opacity = random_scene(40, seed=18)
    zero_opacity.opacity_logit[:] = -1e4
    return {
        "all-zero-opacity": zero_opacity,
        "duplicated": base.subset(np.zeros(40, dtype=int)),
        "collinear": _with_means(base, np.c_[t, 2 * t, -t]),
        "coplanar": _with_means(base, np.c_[t, np.sin(7 * t), np.zeros(40)]),
        "fewer-than-neighbours": random_scene(3, sh_degree=0, seed=19),
        "single": random_scene(1, sh_degree=3, seed=20),
        "sh0": random_scene(40, sh_degree=0, seed=21),
        "sh3": base,
        "empty": random_scene(0, seed=22),
    }


@pytest.mark.parametrize("case", list(_degenerate_scenes()))
@pytest.mark.parametrize("name", NAMES)
def test_degenerate_scenes_give_finite_scores(case, name):
    scene = _degenerate_scenes()[case]
    for kind in (("ucb", "lcb", "quantile", "literal") if "nobeta" not in name else (None,)):
        params = {} if kind is None else {"score": kind}
        s = _score(name, scene, **params)
        assert s.shape == (len(scene),) and np.isfinite(s).all()
        for r in RATIOS:
            assert select_by_ratio(s, r).removed == round(r * len(scene))


def test_view_aware_edge_evidence_only_with_cameras():
    scene = random_scene(500, seed=23)
    spec = get_pruner("betadesc")
    plain = spec.score(scene, PruneContext(params=SMALL))
    cams = [Camera.look_at((4 * np.cos(a), 0.5, 4 * np.sin(a)), (0, 0, 0), width=64, height=48)
            for a in np.linspace(0, 2 * np.pi, 6, endpoint=False)]
    with_cams = spec.score(scene, PruneContext(params={**SMALL, "view_weight": 0.25}, cameras=cams))
    assert not np.array_equal(plain, with_cams)
    assert (with_cams >= plain - 1e-12).sum() > 0.5 * len(scene)  # extra evidence is for retention
    off = spec.score(scene, PruneContext(params=SMALL, cameras=cams))  # view_weight 0: the default
    np.testing.assert_array_equal(off, plain)


def test_view_features_definitions():
    from methods.betadesc.view_aware import view_features

    scene = random_scene(300, seed=24)
    cam = Camera.look_at((0, 0, -6), (0, 0, 0), width=640, height=480, fov_y_deg=60)
    f = view_features(scene, [cam])
    assert f.shape == (300, 10) and np.isfinite(f).all()
    seen = f[:, 0] == 1
    assert seen.sum() > 250
    d = np.linalg.norm(scene.means.astype(np.float64) - cam.center, axis=1)
    diag = np.linalg.norm(scene.means.max(0).astype(np.float64) - scene.means.min(0))
    np.testing.assert_allclose(f[seen, 1], d[seen] / diag, rtol=1e-6)
    np.testing.assert_allclose(f[seen, 3], 0.0, atol=1e-9)  # one camera: no spread
    assert ((f[:, 4:] >= 0) & (f[:, 4:] <= 1 + 1e-12)).all()
    assert np.all(f[~seen] == 0)


def test_edge_proxy_is_opacity_times_grazing_share():
    from methods.betadesc.view_aware import edge_proxy

    # two flat splats at the origin-ish, short axis along z (normal = z): seen from +z they face the
    # camera (not grazing), seen from +x they are edge-on (grazing)
    scene = GaussianScene.from_arrays(
        means=[[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]], scales_log=[[-2, -2, -6], [-2, -2, -6]],
        quats=[[1, 0, 0, 0], [1, 0, 0, 0]], opacity_logit=[2.0, -1.0], sh_dc=np.zeros((2, 3)))
    o = 1 / (1 + np.exp(-scene.opacity_logit.astype(np.float64)))
    facing = Camera.look_at((0.05, 0, 5), (0.05, 0, 0), up=(0, 1, 0))
    edge_on = Camera.look_at((5, 0, 0), (0, 0, 0), up=(0, 1, 0))
    np.testing.assert_allclose(edge_proxy(scene, [facing], o), 0.0)
    np.testing.assert_allclose(edge_proxy(scene, [edge_on], o), o)
    np.testing.assert_allclose(edge_proxy(scene, [facing, edge_on], o), 0.5 * o)
    behind = Camera.look_at((-5, 0, 0), (-10, 0, 0), up=(0, 1, 0))  # looks away: sees nothing
    np.testing.assert_allclose(edge_proxy(scene, [behind, edge_on], o), o)


def _plane_pole_floaters() -> tuple[GaussianScene, np.ndarray]:
    """A redundant grey plane of flat opaque discs, a thin opaque green pole of needles, and faint
    random floaters; labels 0 / 1 / 2."""
    rng = np.random.default_rng(0)
    n1, n2, n3 = 4000, 300, 300
    plane = np.c_[rng.uniform(-1, 1, (n1, 2)), np.zeros(n1)]
    pole = np.c_[0.3 + rng.normal(0, 0.002, (n2, 2)), rng.uniform(0, 1, n2)]
    floaters = rng.uniform([-1, -1, 0.2], [1, 1, 1], (n3, 3))
    scales = np.r_[np.tile([-3.5, -3.5, -8.0], (n1, 1)), np.tile([-7.0, -7.0, -3.5], (n2, 1)),
                   np.full((n3, 3), -4.0)] + rng.normal(0, 0.1, (n1 + n2 + n3, 3))
    quats = np.r_[np.tile([1.0, 0, 0, 0], (n1 + n2, 1)), rng.normal(size=(n3, 4))]
    opacity = np.r_[rng.normal(3, 0.5, n1 + n2), rng.normal(-3, 0.5, n3)]
    colour = np.r_[0.5 + rng.normal(0, 0.05, (n1, 3)), [-1.0, 1.0, -1.0] + rng.normal(0, 0.3, (n2, 3)),
                   rng.normal(0, 1, (n3, 3))]
    scene = GaussianScene.from_arrays(np.r_[plane, pole, floaters], scales, quats, opacity, colour)
    return scene, np.r_[np.zeros(n1), np.ones(n2), np.full(n3, 2)]


def _removed(scene, label, ratio, **params):
    keep = select_by_ratio(get_pruner("betadesc").score(scene, PruneContext(params=params)), ratio).keep
    return [int((~keep & (label == c)).sum()) for c in range(3)]


def test_keeps_thin_structure_and_the_literal_sign_removes_it_first():
    # the v1 reading (the default before issue 13), by parameters
    scene, label = _plane_pole_floaters()

    def removed(ratio, **params):
        return _removed(scene, label, ratio, reading="v1", **params)

    plane, pole, floaters = removed(0.3)
    assert pole == 0 and plane > 1000  # the redundant plane goes, the pole stays
    assert removed(0.1, score="literal")[1] == 300  # the paper's literal sign removes the pole first
    _, pole_oh, floaters_oh = removed(0.3, preset="opacity-heavy")
    assert pole_oh == 0 and floaters_oh >= 285 > floaters  # opacity emphasis also clears the floaters


def test_the_literal_u_reads_a_plane_as_distinctive():
    """Characterisation of round one's default (and paper-literal): u = std across descriptor
    dimensions is high for the peaked FPFH histograms of a plane and low for a pole, so on this scene
    the pole and the faint floaters go before the redundant plane (v1's dispersion u did the reverse)."""
    from methods.betadesc.pipeline import components

    scene, label = _plane_pole_floaters()
    for reading in ("round-one", "paper-literal"):
        plane, pole, floaters = _removed(scene, label, 0.3, reading=reading)
        assert (pole, floaters) == (300, 300) and plane == 780
        c = components(scene, get_pruner("betadesc").parse_params({"reading": reading}))
        assert c.u[label == 0].mean() > 0.8 > 0.4 > c.u[label == 1].mean()
    assert _removed(scene, label, 0.3, reading="round-one", u_def="dispersion")[1] < 30
