"""The projection in numpy (the GL renderer's CPU path, no torch) against the same code in torch
(the reference renderer's, autograd): the same splats kept, values within float32 rounding (their
``exp``/``log`` kernels and torch's ``scalar / tensor``, a reciprocal times the scalar, may differ
in the last bits), and the GL render of a scene equal to within that rounding either way."""

from __future__ import annotations

import numpy as np
import pytest

from harness.core.cameras import Camera
from renderers.gl import pack_instances
from renderers.projection import project_arrays, project_gaussians
from tests.scene_factory import random_scene
from tests.test_view_filter import FIELDS, _camera, _scene


@pytest.mark.parametrize("seed", range(6))
def test_numpy_and_torch_projections_agree(seed):
    scene = _scene(600, seed, [0, 1, 3][seed % 3], ties=seed % 2 == 0)
    cam = _camera(seed, size=(96, 72))
    a, t = project_arrays(scene, cam), project_gaussians(scene, cam, device="cpu")
    assert isinstance(a.ids, np.ndarray) and a.ids.dtype == np.int64
    assert np.array_equal(a.ids, t.ids.numpy()) and len(a.ids) > 0
    for name in FIELDS:
        x, y = getattr(a, name), getattr(t, name).numpy()
        assert x.dtype == np.float32 == y.dtype, name
        np.testing.assert_allclose(x, y, rtol=2e-6, atol=1e-6, err_msg=name)
    pa, pt = pack_instances(a), pack_instances(t)
    assert np.array_equal(pa.ids, pt.ids)
    np.testing.assert_allclose(pa.records, pt.records, rtol=2e-6, atol=1e-6)


def test_float64_splats_keep_their_precision():
    """A torch SplatTensors of float64 projects in float64 (the camera is not rounded to float32 first)."""
    import torch

    from renderers.projection import SplatTensors

    scene = random_scene(200, sh_degree=1, seed=3)
    cam = Camera.look_at((0.0, 0.0, -4.0), (0.0, 0.0, 0.0), fov_y_deg=50, width=64, height=48)
    p = project_gaussians(SplatTensors.from_scene(scene, device="cpu", dtype=torch.float64), cam)
    assert p.means2d.dtype == torch.float64 and p.radii.dtype == torch.float64
    np.testing.assert_allclose(p.means2d.numpy(), project_arrays(scene, cam).means2d, rtol=1e-5)


@pytest.mark.gl
def test_the_gl_render_is_the_same_from_either_projection():
    from renderers.gl import GLRenderer
    from tests.gl_support import require_gl

    require_gl()
    scene = _scene(400, 11, 3, ties=False)
    cam = _camera(11, size=(80, 64))
    with GLRenderer(device="cpu") as gl:
        assert gl.projection_device() is None  # numpy
        img = gl.render(scene, cam)
        diff = np.abs(gl.draw(pack_instances(project_gaussians(scene, cam, device="cpu"))) - img)
    # float rounding everywhere, except a pixel where a splat's alpha sits within an ulp of 1/255
    # and the cut flips (module docstring of renderers.gl): it differs by about colour/255
    assert (diff > 2e-5).mean() < 1e-3 and diff.max() < 0.01
