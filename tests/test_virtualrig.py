"""The ``virtual-rig`` pruner: it cannot see the test rigs, its rig comes from the splats, and its
score is exactly LightGS's accumulation over that rig (checked against a dense computation)."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
import torch

from harness.core.scene import GaussianScene
from harness.run.cache.versions import project_closure
from methods import PruneContext, get_pruner
from methods.lightgs.significance import resolve_backend, significance, volume_factor
from methods.virtualrig import VirtualRigParams, virtual_cameras
from methods.virtualrig.rig import MIN_CELLS, REACH_SHARE, farthest_points, shell_multipliers
from methods.virtualrig.shape import analyse, free_reach, ray_enclosure, weighted_quantile
from renderers.projection import project_gaussians
from tests.scene_factory import random_scene
from tests.test_lightgs import _cams, _scene, dense_significance

REPO = __import__("pathlib").Path(__file__).resolve().parent.parent


# ------------------------------------------------------------------ the leak test
@pytest.mark.parametrize("module", ["methods.virtualrig", "methods.betadesc.vr"])
def test_cannot_import_the_test_rigs(module):
    """No module the pruner depends on (statically, lazy imports included) is harness.views: the
    pruner cannot mirror the protocols that score it."""
    closure = project_closure(module)
    assert module in closure and "methods.lightgs.significance" in closure
    assert not [m for m in closure if m == "harness.views" or m.startswith("harness.views.")]


def test_scoring_loads_no_test_rig_module():
    """The same at run time, in a fresh interpreter: scoring imports nothing of harness.views."""
    code = ("import sys, json; from tests.scene_factory import random_scene; from methods import get_pruner, "
            "PruneContext; s = random_scene(300, seed=1); s.means[:] *= 0.3; "
            "get_pruner('virtual-rig').score(s, PruneContext(params={'views': 6, 'resolution': 32})); "
            "print(json.dumps(sorted(m for m in sys.modules if m.startswith('harness.views'))))")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert json.loads(out.stdout.strip().splitlines()[-1]) == []


# ------------------------------------------------------------------ the shared significance function
@pytest.mark.parametrize("early_stop", [True, False])
def test_reference_backend_matches_dense_and_pairs(early_stop):
    """The CUDA path (the reference rasterizer's statistics; run here on the CPU) and the CPU path
    (pixel pairs) both equal the dense per-pixel computation."""
    scene, cams = _scene(), _cams()
    dense = dense_significance(scene, cams, early_stop)
    pairs = significance(scene, cams, longest_side=0, early_stop=early_stop, backend="pairs")
    ref = significance(scene, cams, longest_side=0, early_stop=early_stop, backend="reference")
    np.testing.assert_allclose(pairs, dense, rtol=2e-5, atol=1e-6)
    np.testing.assert_allclose(ref, dense, rtol=1e-4, atol=1e-5)


def test_auto_backend_follows_the_device():
    assert resolve_backend("auto", "cpu") == "sweep"
    assert resolve_backend("auto", "cuda") == resolve_backend("auto", "cuda:0") == "reference"
    with pytest.raises(ValueError, match="unknown significance backend"):
        resolve_backend("gl", "cpu")


# ------------------------------------------------------------------ scene-shape analysis
def _scene_from(points: np.ndarray, scale: float, opacity_logit: float = 4.0) -> GaussianScene:
    n = len(points)
    return GaussianScene.from_arrays(means=points, scales_log=np.full((n, 3), math.log(scale)),
                                     quats=np.tile([1.0, 0, 0, 0], (n, 1)), opacity_logit=np.full(n, opacity_logit),
                                     sh_dc=np.full((n, 3), 0.5), sh_rest=np.zeros((n, 0, 3)))


def _solid_ball(n=6000, seed=0):
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, 3))
    return p / np.linalg.norm(p, axis=1, keepdims=True) * rng.uniform(size=(n, 1)) ** (1 / 3)


def _room(n=12000, seed=0):
    """The six walls of the cube [-4, 4]³ and a small dense object at its centre (a capture's subject)."""
    rng = np.random.default_rng(seed)
    walls = rng.uniform(-4, 4, size=(n, 3))
    axis, side = rng.integers(3, size=n), rng.choice([-4.0, 4.0], size=n)
    walls[np.arange(n), axis] = side
    return np.concatenate([walls, 0.3 * _solid_ball(n // 4, seed + 1)])


def test_weighted_quantile_is_the_inverted_cdf_of_the_repeated_values():
    rng = np.random.default_rng(3)
    v, w = rng.normal(size=40), rng.integers(1, 6, size=40)
    for q in (0.0, 0.1, 0.25, 0.5, 0.9, 1.0):
        expect = np.quantile(np.repeat(v, w), q, method="inverted_cdf")
        assert weighted_quantile(v, w.astype(float), q) == pytest.approx(expect)


def test_ray_enclosure_by_hand():
    occ = np.zeros((5, 5, 5), bool)
    occ[4, 2, 2] = True  # one occupied cell on the +x side of the start
    dirs = np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    np.testing.assert_allclose(ray_enclosure(occ, np.array([[2.5, 2.5, 2.5]]), dirs), [0.25])
    assert ray_enclosure(np.ones((3, 3, 3), bool), np.array([[1.5, 1.5, 1.5]]), dirs)[0] == 1.0


def test_free_reach_by_hand():
    occ = np.zeros((9, 9, 9), bool)
    occ[4, 4, 4] = True  # the subject's own cell: within the spare ball, not an obstacle
    occ[8, :, :] = True  # a wall at x = 8
    start = np.array([4.5, 4.5, 4.5])
    dirs = np.array([[1.0, 0, 0], [-1.0, 0, 0]])
    # +x: free up to the last half-step before cell 8 (t = 3.0 → x = 7.5); −x: in cell 0 up to x = 0.0 (t = 4.5)
    np.testing.assert_allclose(free_reach(occ, start, dirs, spare=1.5), [3.0, 4.5])
    # without the spare ball the −x ray stops at its first step, x = 4.0, in the occupied cell 4
    np.testing.assert_allclose(free_reach(occ, start, dirs, spare=0.0), [3.0, 0.0])


def test_an_object_is_seen_from_outside_and_a_room_from_inside():
    ball = analyse(_scene_from(_solid_ball(), 0.05))
    assert ball.kind == "object" and ball.enclosure < 0.8
    assert np.linalg.norm(ball.center) < 0.05 and 0.8 < ball.radius < 1.0  # P95 of r: 0.95^(1/3) ≈ 0.983
    room = analyse(_scene_from(_room(), 0.15))
    assert room.kind == "room" and room.enclosure >= 0.9
    assert len(room.probes) > 0 and np.all(np.abs(room.probes) < 4.0)  # inside the walls
    assert np.all(np.diff(room.probe_clearance) <= 0)  # most clearance first
    assert np.linalg.norm(room.peak) < 2 * room.cell  # the subject: the dense object at the centre


def test_analysis_rejects_an_empty_scene():
    with pytest.raises(ValueError, match="empty"):
        analyse(random_scene(0))


# ------------------------------------------------------------------ the rig
def test_outside_in_rig_frames_the_bounding_sphere():
    scene = _scene_from(_solid_ball(), 0.05)
    p = VirtualRigParams(views=20, shells=2, radius_min=0.5, radius_max=1.0, fov_deg=50.0, resolution=64)
    shape, cams = virtual_cameras(scene, p)
    assert len(cams) == 20 and len({c.name for c in cams}) == 20
    d_fit = shape.radius / math.sin(math.radians(25.0))
    dist = sorted(np.linalg.norm(c.center - shape.center) for c in cams)
    np.testing.assert_allclose(dist[:10], 0.5 * d_fit, rtol=1e-9)
    np.testing.assert_allclose(dist[10:], d_fit, rtol=1e-9)
    for c in cams:  # every camera looks at the centre; the far shell sees the whole sphere
        to_c = (shape.center - c.center) / np.linalg.norm(shape.center - c.center)
        assert c.forward @ to_c == pytest.approx(1.0)
        assert c.width == c.height == 64 and math.degrees(c.fov_y) == pytest.approx(50.0)
    np.testing.assert_allclose(shell_multipliers(3, 0.25, 1.0), [1.0, 0.5, 0.25])


def test_inside_out_rig_circles_the_subject_inside_the_room():
    scene = _scene_from(_room(), 0.15)
    shape, cams = virtual_cameras(scene, VirtualRigParams(views=24, resolution=32, fov_deg=50.0, positions="around"))
    assert shape.kind == "room" and len(cams) == 24
    dist = np.array([np.linalg.norm(c.center - shape.peak) for c in cams])
    assert np.all(dist >= MIN_CELLS * shape.cell - 1e-9) and np.all(np.abs([c.center for c in cams]) < 4.0)
    assert np.median(dist) > REACH_SHARE * 2.0  # the walls are ≥ 4 away in every direction: cameras stand off
    for c in cams:
        to_peak = (shape.peak - c.center) / np.linalg.norm(shape.peak - c.center)
        assert c.forward @ to_peak == pytest.approx(1.0) and math.degrees(c.fov_y) == pytest.approx(50.0)


def test_enclosed_inside_out_rig_is_cubes_of_views_from_free_space():
    scene = _scene_from(_room(), 0.15)
    shape, cams = virtual_cameras(scene, VirtualRigParams(views=14, resolution=32, positions="enclosed"))
    assert shape.kind == "room" and len(cams) == 18  # ⌈14 / 6⌉ = 3 positions × 6 faces
    for k in range(3):
        face = cams[6 * k: 6 * k + 6]
        eye = face[0].center
        assert all(np.allclose(c.center, eye) for c in face)
        fwd = np.array([c.forward for c in face])
        np.testing.assert_allclose(fwd[:3] @ fwd[:3].T, np.eye(3), atol=1e-9)  # three orthogonal axes
        np.testing.assert_allclose(fwd[3:], -fwd[:3], atol=1e-12)  # and their opposites
        assert math.degrees(face[0].fov_x) == pytest.approx(90.0)


def test_farthest_points_spreads_out():
    pts = np.array([[0.0, 0, 0], [0.1, 0, 0], [5.0, 0, 0], [0, 3.0, 0]])
    assert farthest_points(pts, 3).tolist() == [0, 2, 3]
    assert farthest_points(pts, 10).tolist() == [0, 2, 3, 1]


def test_forcing_enclosed_inside_out_without_free_space_is_one_clear_error():
    with pytest.raises(ValueError, match="no enclosed free space"):
        virtual_cameras(_scene_from(_solid_ball(), 0.05), VirtualRigParams(rig="inside-out", positions="enclosed"))


# ------------------------------------------------------------------ the pruner
def _small_object():
    s = _scene_from(_solid_ball(800, seed=5), 0.04, opacity_logit=0.0)
    s.opacity_logit[:] = np.random.default_rng(5).normal(0.0, 2.0, len(s)).astype(np.float32)
    return s


def test_score_is_lightgs_over_the_virtual_cameras():
    """virtual-rig = LightGSPrune handed the virtual rig as its training views (same accumulation,
    same volume term), and = the dense computation over those views."""
    scene = _small_object()
    params = {"views": 6, "resolution": 40}
    got = get_pruner("virtual-rig").score(scene, PruneContext(params=params))
    _, cams = virtual_cameras(scene, VirtualRigParams.parse(params))
    lightgs = get_pruner("lightgs").score(scene, PruneContext(params={"train_longest_side": 0}, cameras=cams))
    np.testing.assert_array_equal(got, lightgs)
    dense = dense_significance(scene, cams, early_stop=True) * volume_factor(scene.scales_log)
    np.testing.assert_allclose(got, dense, rtol=2e-5, atol=1e-6)
    assert (got > 0).mean() > 0.5


def test_score_is_deterministic_and_the_rig_seed_moves_the_rig():
    scene = _small_object()
    spec = get_pruner("virtual-rig")
    a = spec.score(scene, PruneContext(params={"views": 6, "resolution": 24}, seed=1))
    b = spec.score(scene, PruneContext(params={"views": 6, "resolution": 24}, seed=2))  # run seed: unused
    c = spec.score(scene, PruneContext(params={"views": 6, "resolution": 24, "rig_seed": 3}))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_registered_camera_free():
    spec = get_pruner("virtual-rig")
    assert spec.group == "camera-free" and not spec.needs and not spec.wants_cameras(spec.parse_params())
    assert get_pruner("virtual-rig").score(random_scene(0), PruneContext()).shape == (0,)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device: the CUDA path runs the reference "
                    "backend, checked on the CPU above")
def test_cuda_matches_cpu():
    scene = _small_object()
    spec = get_pruner("virtual-rig")
    cpu = spec.score(scene, PruneContext(params={"views": 6, "resolution": 40}))
    gpu = spec.score(scene, PruneContext(params={"views": 6, "resolution": 40}, device="cuda"))
    np.testing.assert_allclose(gpu, cpu, rtol=1e-4, atol=1e-5)


def test_projection_sees_the_content_from_every_view():
    scene = _small_object()
    _, cams = virtual_cameras(scene, VirtualRigParams(views=8, resolution=32))
    with torch.no_grad():
        assert all(len(project_gaussians(scene, c, device="cpu").ids) > 0.5 * len(scene) for c in cams)
