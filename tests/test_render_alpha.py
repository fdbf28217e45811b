"""``render_with_alpha``: both renderers return (image, alpha = 1 − T), consistent with their images
(image(bg) = C + (1 − alpha)·bg) and with each other; ``render`` is unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from harness.core.cameras import Camera
from renderers.gl import GLRenderer, GLUnavailable
from renderers.reference import ReferenceRenderer
from tests.scene_factory import random_scene

pytestmark = pytest.mark.gl


@pytest.fixture(scope="module")
def gl():
    renderer = GLRenderer()
    try:
        renderer._ensure_context()
    except GLUnavailable as err:
        pytest.skip(f"no EGL OpenGL context on this machine: {err}")
    yield renderer
    renderer.close()


def _scene_and_camera():
    scene = random_scene(300, 1, seed=4)
    cam = Camera.look_at((0.0, 0.0, -4.0), (0.0, 0.0, 0.0), width=64, height=48)
    return scene, cam


@pytest.mark.parametrize("which", ["gl", "reference"])
def test_alpha_is_one_minus_transmittance(gl, which):
    r = gl if which == "gl" else ReferenceRenderer(device="cpu")
    scene, cam = _scene_and_camera()
    bg = np.array([0.2, 0.5, 1.0], np.float32)
    img0, alpha = r.render_with_alpha(scene, cam, (0.0, 0.0, 0.0))
    img_bg, alpha_bg = r.render_with_alpha(scene, cam, tuple(bg))
    assert alpha.shape == img0.shape[:2] and alpha.dtype == np.float32
    np.testing.assert_array_equal(alpha, alpha_bg)
    np.testing.assert_allclose(img_bg, img0 + (1.0 - alpha)[..., None] * bg, atol=2e-6)
    np.testing.assert_array_equal(img_bg, r.render(scene, cam, tuple(bg)))
    assert 0.0 <= alpha.min() and alpha.max() <= 1.0 and (alpha > 0.5).any() and (alpha == 0).any()


def test_renderers_agree_on_alpha(gl):
    scene, cam = _scene_and_camera()
    _, a_gl = gl.render_with_alpha(scene, cam)
    _, a_ref = ReferenceRenderer(device="cpu").render_with_alpha(scene, cam)
    # float rounding, plus the rare pixel where one splat's α sits within ulps of the 1/255 cut
    close = np.abs(a_gl - a_ref) <= 1e-5
    assert close.mean() > 0.995 and np.abs(a_gl - a_ref).max() < 0.02
