"""Renderers at the edges of the 3DGS math: near plane, tiny/huge/near-singular covariances, the α
clamp and cut, and a million splats on one pixel. Both renderers must stay finite, match closed
forms where the math gives one, and agree with each other (GL tests skip with the reason without EGL).

Camera: identity pose (world = camera frame), f = 20 px, principal point (W/2 + ½, H/2 + ½), so a splat
at (0, 0, z) projects exactly onto the centre of pixel (W/2, H/2) (means2d = f·x/z + c − ½). Colours
from the DC term only: c = SH_C0·dc + ½.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from harness.core.cameras import Camera
from harness.core.scene import SH_C0, GaussianScene
from renderers.reference import ReferenceRenderer
from tests.stress.budget import examples, n

pytestmark = pytest.mark.stress

W, H, F = 16, 12, 20.0
CAM = Camera(np.eye(4), F, F, W / 2 + 0.5, H / 2 + 0.5, W, H, "stress")
BG = (0.2, 0.4, 0.6)
AGREE = 2e-4  # max |GL − reference| per pixel (float32 exp in GLSL vs torch)


def logit(p):
    p = np.asarray(p, np.float64)
    return np.log(p) - np.log1p(-p)


def scene(means, scales=1e-3, opac=0.9, colour=(1.0, 0.5, 0.0), quats=(1.0, 0, 0, 0), opacity_logit=None):
    means = np.atleast_2d(np.asarray(means, np.float64))
    m = len(means)
    scales = np.broadcast_to(np.asarray(scales, np.float64), (m, 3))
    col = np.broadcast_to(np.asarray(colour, np.float64), (m, 3))
    return GaussianScene.from_arrays(
        means=means, scales_log=np.log(scales), quats=np.broadcast_to(np.asarray(quats, np.float64), (m, 4)),
        opacity_logit=np.broadcast_to(logit(opac) if opacity_logit is None else opacity_logit, (m,)),
        sh_dc=(col - 0.5) / SH_C0, sh_rest=np.zeros((m, 0, 3)))


@pytest.fixture(scope="module")
def ref():
    return ReferenceRenderer(device="cpu")


@pytest.fixture(scope="module")
def gl():
    try:
        from renderers.gl import GLRenderer, GLUnavailable
    except ImportError as err:
        pytest.skip(f"GL renderer not importable: {err}")
    r = GLRenderer()
    try:
        r.render(scene([0, 0, 2.0]), CAM)
    except GLUnavailable as err:
        pytest.skip(f"no EGL OpenGL context: {err}")
    yield r
    r.close()


def both(gl, ref, sc, background=BG):
    a, b = ref.render(sc, CAM, background), gl.render(sc, CAM, background)
    assert a.shape == b.shape == (H, W, 3) and a.dtype == b.dtype == np.float32
    assert np.isfinite(a).all() and np.isfinite(b).all()
    np.testing.assert_allclose(b, a, rtol=0, atol=AGREE)
    return a


CENTRE = (H // 2, W // 2)


@pytest.mark.parametrize(
    "z, drawn", [(-1.0, False), (0.0, False), (0.1, False), (0.19, False), (0.21, True), (1.0, True)]
)
def test_near_plane_and_behind(gl, ref, stress_counts, z, drawn):
    """Culled at z ≤ 0.2 (the image is the background exactly), drawn just in front."""
    stress_counts.add("renderers", near_plane=1)
    img = both(gl, ref, scene([0, 0, z], scales=0.05))
    is_bg = np.array_equal(img, np.broadcast_to(np.float32(BG), img.shape))
    assert is_bg != drawn


def test_at_the_near_plane_exactly_both_agree(gl, ref, stress_counts):
    stress_counts.add("renderers", near_plane=2)
    for s in (1e-3, 1.0):
        both(gl, ref, scene([0, 0, 0.2], scales=s))


def test_tiny_covariance_is_the_dilation_kernel(gl, ref, stress_counts):
    """Scale 1e-8: Σ′ = 0.3·I, so pixel d away has α = o·exp(−|d|²/0.6)."""
    stress_counts.add("renderers", covariance=1)
    o, c = 0.8, np.array([1.0, 0.5, 0.0])
    img = both(gl, ref, scene([0, 0, 2.0], scales=1e-8, opac=o, colour=c))
    for dy, dx in ((0, 0), (0, 1), (1, 1)):
        a = o * np.exp(-(dx * dx + dy * dy) / 0.6)
        want = a * c + (1 - a) * np.asarray(BG) if a >= 1 / 255 else np.asarray(BG)
        np.testing.assert_allclose(img[CENTRE[0] + dy, CENTRE[1] + dx], want, rtol=0, atol=1e-5)


def test_huge_covariance_covers_the_image_uniformly(gl, ref, stress_counts):
    stress_counts.add("renderers", covariance=1)
    o, c = 0.7, np.array([0.1, 0.9, 0.3])
    img = both(gl, ref, scene([0, 0, 5.0], scales=1e4, opac=o, colour=c))
    np.testing.assert_allclose(img, np.broadcast_to(o * c + (1 - o) * np.asarray(BG), img.shape), atol=1e-5)


@pytest.mark.parametrize("scales, quat", [
    ((1.0, 1e-8, 1e-8), (1, 0, 0, 0)),           # needle across the view
    ((1e-8, 1e-8, 1.0), (1, 0, 0, 0)),           # needle along the view axis (end-on)
    ((1e4, 1e-8, 1e-8), (0.9, 0.1, 0.3, 0.2)),   # condition number 1e24, oblique
    ((10.0, 10.0, 1e-8), (0.7, 0.7, 0.0, 0.0)),  # flat disk seen edge-on
])
def test_nearly_singular_covariances(gl, ref, stress_counts, scales, quat):
    stress_counts.add("renderers", singular=1)
    both(gl, ref, scene([0, 0, 3.0], scales=scales, quats=quat, opac=0.95))


def test_alpha_clamp_at_099(gl, ref, stress_counts):
    """Opacity 1 at the pixel centre: α = 0.99; a second splat behind gets 0.99·0.01 of its colour."""
    stress_counts.add("renderers", alpha=1)
    c1, c2, bg = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), np.asarray(BG)
    sc = scene([[0, 0, 2.0], [0, 0, 3.0]], scales=1e-8, opacity_logit=np.array([40.0, 40.0]))
    sc.sh_dc[1] = (c2 - 0.5) / SH_C0
    sc.sh_dc[0] = (c1 - 0.5) / SH_C0
    img = both(gl, ref, sc)
    want = 0.99 * c1 + 0.01 * 0.99 * c2 + 0.01 * 0.01 * bg
    np.testing.assert_allclose(img[CENTRE], want, rtol=0, atol=1e-5)


@pytest.mark.parametrize("factor, drawn", [(1 - 1e-3, False), (1 + 1e-2, True)])
def test_alpha_cut_at_one_over_255(gl, ref, stress_counts, factor, drawn):
    stress_counts.add("renderers", alpha=1)
    o = factor / 255.0
    c, bg = np.array([1.0, 1.0, 1.0]), np.asarray(BG)
    img = both(gl, ref, scene([0, 0, 2.0], scales=1e-8, opac=o, colour=c))
    ob = 1.0 / (1.0 + np.exp(-np.float32(logit(o))))  # the float32 sigmoid the renderers see
    want = ob * c + (1 - ob) * bg if drawn else bg
    np.testing.assert_allclose(img[CENTRE], want, rtol=0, atol=1e-6)
    others = np.ones((H, W), bool)
    others[CENTRE] = False
    np.testing.assert_array_equal(img[others], np.broadcast_to(np.float32(bg), (H * W - 1, 3)))


def test_a_million_splats_on_one_pixel(gl, ref, stress_counts):
    """N splats at random depths on one pixel centre: T underflows to 0, the images stay finite,
    agree, and the centre pixel is the depth-ordered composite (checked in float64 here)."""
    m = n(100_000, 1_000_000)
    stress_counts.add("renderers", overlapping=1)
    stress_counts.note("renderers", "overlapping_splats_per_pixel", m)
    rng = np.random.default_rng(0)
    z = rng.uniform(1.0, 3.0, m)
    col = rng.uniform(0, 1, (m, 3))
    o = rng.uniform(0.05, 0.5, m)
    sc = scene(np.c_[np.zeros(m), np.zeros(m), z], scales=1e-8, opac=o, colour=col)
    img = both(gl, ref, sc)
    order = np.argsort(sc.means[:, 2], kind="stable")
    a = np.minimum(0.99, 1 / (1 + np.exp(-sc.opacity_logit[order].astype(np.float64))))
    t = np.concatenate([[1.0], np.cumprod(1 - a)[:-1]])
    c = np.maximum(SH_C0 * sc.sh_dc[order].astype(np.float64) + 0.5, 0)
    np.testing.assert_allclose(img[CENTRE], (a * t) @ c, rtol=0, atol=1e-4)


@examples(8, 300)
@given(st.lists(st.tuples(st.floats(-0.5, 0.5), st.floats(-0.5, 0.5), st.floats(-1.0, 6.0),
                          st.floats(-8, 4), st.floats(-8, 4), st.floats(-8, 4), st.floats(-30, 30)),
                min_size=1, max_size=40),
       st.integers(0, 2**31 - 1))
def test_random_extreme_splats_agree(gl, ref, stress_counts, rows, seed):
    """Positions around and behind the near plane, log10 scales in [−8, 4], opacity logits ±30."""
    rng = np.random.default_rng(seed)
    r = np.asarray(rows)
    m = len(r)
    sc = GaussianScene.from_arrays(
        means=r[:, :3] * np.c_[r[:, 2:3], r[:, 2:3], np.ones(m)], scales_log=r[:, 3:6] * np.log(10),
        quats=rng.normal(size=(m, 4)) + [2.0, 0, 0, 0], opacity_logit=r[:, 6],
        sh_dc=rng.normal(0, 1, (m, 3)), sh_rest=rng.normal(0, 0.3, (m, 3, 3)))
    stress_counts.add("renderers", random=1)
    both(gl, ref, sc)
