"""A view projected once and filtered per keep mask renders exactly as the pruned scene does.

The study renders each pruned set as :meth:`renderers.gl.PackedView.kept` of its view's full
packing instead of projecting, sorting and packing ``scene.subset(keep)`` again. The independent
truth is that second path, the plain render of the pruned scene: projections, packed records and GL
images must be equal bit for bit, on generated scenes (hypothesis: sizes around the SIMD and
parallel-chunk boundaries, splats behind the camera, huge and tiny, ties in depth, every opacity)
and on the real ones.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from harness.core.cameras import Camera
from harness.core.scene import GaussianScene
from renderers.gl import pack_instances
from renderers.projection import project_arrays, project_gaussians, sigmoid
from tests.scene_factory import random_scene
from tests.test_gl_renderer import gl  # noqa: F401  (fixture: the GL renderer, one context, or a skip)

FIELDS = ("means2d", "conics", "depths", "radii", "colors", "opacities")


def _scene(n: int, seed: int, sh_degree: int, ties: bool) -> GaussianScene:
    """A random scene with the awkward cases mixed in: wide scale and opacity ranges, splats behind
    and beside the camera, zero-norm quaternions, and (``ties``) splats sharing one depth."""
    base = random_scene(n, sh_degree=sh_degree, seed=seed)
    rng = np.random.default_rng(seed + 1)
    means = base.means * rng.choice([0.5, 1.0, 3.0], size=(n, 1))
    if ties and n:
        means[rng.random(n) < 0.5, 2] = 0.25  # one depth for half of them (camera on the z axis)
    scales = base.scales_log + rng.choice([-3.0, 0.0, 0.0, 2.0, 6.0], size=(n, 1))
    quats = base.quats.copy()
    quats[rng.random(n) < 0.05] = 0.0
    logits = base.opacity_logit * rng.choice([0.5, 1.0, 4.0], size=n)
    return GaussianScene.from_arrays(means=means, scales_log=scales, quats=quats, opacity_logit=logits,
                                     sh_dc=base.sh_dc, sh_rest=base.sh_rest)


def _camera(seed: int, size=(48, 40)) -> Camera:
    rng = np.random.default_rng(seed)
    eye = np.array([0.0, 0.0, -4.0]) + rng.normal(0, 0.5, 3)
    return Camera.look_at(eye, (0.0, 0.0, 0.0), fov_y_deg=float(rng.uniform(30, 80)), width=size[0], height=size[1])


#: the projection in each array library (renderers.arrays): torch (the reference renderer, the pruners)
#: and numpy (the GL renderer on the CPU)
PROJECTIONS = {"torch": lambda scene, cam: project_gaussians(scene, cam, device="cpu"), "numpy": project_arrays}


def _numpy(x) -> np.ndarray:
    return x.numpy() if isinstance(x, torch.Tensor) else x


def _assert_projection_filters(scene: GaussianScene, cam: Camera, keep: np.ndarray) -> None:
    for project in PROJECTIONS.values():
        full, sub = project(scene, cam), project(scene.subset(keep), cam)
        in_full = keep[_numpy(full.ids)]
        assert np.array_equal(_numpy(full.ids)[in_full], np.flatnonzero(keep)[_numpy(sub.ids)])
        for name in FIELDS:
            a, b = _numpy(getattr(full, name))[in_full], _numpy(getattr(sub, name))
            assert np.array_equal(a, b), f"{name}: {int((a != b).reshape(len(b), -1).any(-1).sum())} splats differ"
        whole, pruned = pack_instances(full).kept(keep), pack_instances(sub)
        assert np.array_equal(whole.records, pruned.records)
        assert np.array_equal(whole.ids, np.flatnonzero(keep)[pruned.ids])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(0, 700), seed=st.integers(0, 2**16), sh=st.sampled_from([0, 1, 3]), ties=st.booleans(),
       frac=st.sampled_from([0.0, 0.1, 0.5, 0.9, 1.0]))
def test_projection_and_packing_of_a_subset_are_the_full_ones_filtered(n, seed, sh, ties, frac):
    scene = _scene(n, seed, sh, ties)
    keep = np.random.default_rng(seed + 2).random(n) < frac
    _assert_projection_filters(scene, _camera(seed), keep)


@pytest.mark.parametrize("n", [40_000, 70_001])
def test_filtering_large_scenes(n):
    """Beyond torch's parallel grain (32,768 elements), where elementwise work is split across threads
    and each thread's chunk ends in a tail of its own."""
    threads = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        scene = _scene(n, 7, 0, ties=False)
        keep = np.random.default_rng(n).random(n) < 0.7
        _assert_projection_filters(scene, _camera(3, size=(64, 64)), keep)
    finally:
        torch.set_num_threads(threads)


def test_sigmoid_values_do_not_depend_on_position():
    x = torch.randn(3 * 16384 + 76) * 6
    whole = sigmoid(x)
    for k in (1, 13, 31, 32, 33, 16383, 16389):
        assert torch.equal(sigmoid(x[k:]), whole[k:])
    assert torch.equal(sigmoid(x.reshape(-1, 4)), whole.reshape(-1, 4))
    assert torch.allclose(whole, torch.sigmoid(x), rtol=0, atol=2e-7)
    assert sigmoid(torch.tensor([-200.0, 200.0])).tolist() == [0.0, 1.0]
    g = torch.randn(40, requires_grad=True)
    sigmoid(g).sum().backward()
    assert torch.allclose(g.grad, torch.sigmoid(g) * (1 - torch.sigmoid(g)), atol=1e-6)


# ------------------------------------------------------------------------------------------ GL images

def _assert_renders_equal(gl, scene, cam, keeps, background=(0.1, 0.2, 0.3)) -> None:
    view = gl.pack(scene, cam)
    assert np.array_equal(gl.draw(view, background), gl.render(scene, cam, background))
    for keep in keeps:
        img, alpha = gl.draw(view.kept(keep), background, with_alpha=True)
        ref_img, ref_alpha = gl.render_with_alpha(scene.subset(keep), cam, background)
        assert np.array_equal(img, ref_img) and np.array_equal(alpha, ref_alpha)


@pytest.mark.gl
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(n=st.integers(1, 500), seed=st.integers(0, 2**16), ties=st.booleans())
def test_gl_render_of_a_filtered_view_equals_the_pruned_scene(gl, n, seed, ties):
    scene = _scene(n, seed, 1, ties)
    rng = np.random.default_rng(seed + 3)
    _assert_renders_equal(gl, scene, _camera(seed), [rng.random(n) < f for f in (0.3, 0.9)])


@pytest.mark.gl
@pytest.mark.data
@pytest.mark.parametrize("name", ["grape-small", "luigi", pytest.param("bonsai-7k-mini", marks=pytest.mark.slow),
                                  pytest.param("bonsai-7k", marks=pytest.mark.slow)])
def test_gl_real_scenes_filtered_equal_pruned(gl, name):
    from harness.io import datasets
    from harness.io.scenes import load_scene
    from harness.views.rigs import scene_rig

    path = datasets.scene_path(name)
    if not path.exists():
        pytest.skip(f"{name} is not on this machine ({path}); run `harness fetch`")
    scene = load_scene(path)
    views = scene_rig(name, scene, "default", n_train=0, n_test=2, longest_side=160, aspect=None, seed=0)
    rng = np.random.default_rng(0)
    scores = rng.random(len(scene))
    keeps = [scores > q for q in (0.1, 0.3, 0.7)] + [np.argsort(scene.opacity_logit, kind="stable") >= len(scene) // 2]
    for cam in views.test:
        _assert_renders_equal(gl, scene, cam, keeps, background=(0.0, 0.0, 0.0))
