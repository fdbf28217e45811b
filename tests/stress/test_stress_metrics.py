"""PSNR / SSIM / LPIPS on constant, identical, single-pixel-different and extreme-valued images.

Truth: PSNR from the closed form 10·log10(1/MSE) of the [0, 1]-clamped images in float64; SSIM from
a brute-force implementation of the documented 3DGS convention (11×11 Gaussian window σ = 1.5 applied
as a full 2-D sum with zero padding, population moments, C1 = 0.01², C2 = 0.03², mean over all
pixels and channels) written here independently of the separable filters of harness.metrics.ssim.
LPIPS: identical → 0, any difference → finite and > 0 (weights needed; skipped without them).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from harness.core.errors import InputError
from harness.metrics.psnr import psnr
from harness.metrics.ssim import ssim
from tests.stress.budget import examples

pytestmark = pytest.mark.stress

C1, C2 = 0.01**2, 0.03**2


def ssim_brute(a: np.ndarray, b: np.ndarray) -> float:
    x = np.clip(np.asarray(a, np.float64), 0, 1)
    y = np.clip(np.asarray(b, np.float64), 0, 1)
    r = 5
    i = np.arange(-r, r + 1)
    g2 = np.exp(-(i[:, None] ** 2 + i[None, :] ** 2) / (2 * 1.5**2))
    g2 /= g2.sum()
    h, w, _ = x.shape

    def blur(z):
        p = np.zeros((h + 2 * r, w + 2 * r, 3))
        p[r:r + h, r:r + w] = z
        out = np.zeros_like(z)
        for dy in range(2 * r + 1):
            for dx in range(2 * r + 1):
                out += g2[dy, dx] * p[dy:dy + h, dx:dx + w]
        return out

    mx, my = blur(x), blur(y)
    sxx, syy, sxy = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    m = (2 * mx * my + C1) * (2 * sxy + C2) / ((mx * mx + my * my + C1) * (sxx + syy + C2))
    return float(m.mean())


def psnr_closed(a, b) -> float:
    d = np.clip(np.asarray(a, np.float64), 0, 1) - np.clip(np.asarray(b, np.float64), 0, 1)
    m = float(np.mean(d * d))
    return math.inf if m == 0 else 10 * math.log10(1 / m)


@pytest.fixture(scope="module")
def lpips():
    from harness.metrics.lpips_vgg import LpipsVGG

    try:
        return LpipsVGG(device="cpu")
    except InputError as err:
        pytest.skip(f"LPIPS-VGG weights unavailable: {err}")


SHAPE = (20, 24, 3)
LEVELS = (0.0, 1e-30, 0.25, 0.5, 1.0)


@pytest.mark.parametrize("v", LEVELS + (-5.0, 7.0, 1e30))
def test_identical_constant_images(lpips, stress_counts, v):
    stress_counts.add("metrics", constant=1)
    a = np.full(SHAPE, v, np.float32)
    assert psnr(a, a.copy()) == math.inf
    assert ssim(a, a.copy()) == pytest.approx(1.0, abs=1e-12)
    d = lpips(a, a.copy())
    assert math.isfinite(d) and abs(d) <= 1e-6


@pytest.mark.parametrize("u", LEVELS)
@pytest.mark.parametrize("v", LEVELS)
def test_different_constants(stress_counts, u, v):
    stress_counts.add("metrics", constant=1)
    a, b = np.full(SHAPE, u, np.float32), np.full(SHAPE, v, np.float32)
    assert psnr(a, b) == pytest.approx(psnr_closed(a, b), rel=1e-12)
    assert ssim(a, b) == pytest.approx(ssim_brute(a, b), abs=1e-9)


@pytest.mark.parametrize("delta", [1e-7, 1e-3, 0.5, 1.0, 1e30])
def test_single_pixel_difference(lpips, stress_counts, delta):
    stress_counts.add("metrics", single_pixel=1)
    a = np.random.default_rng(0).uniform(0, 1, SHAPE).astype(np.float32)
    b = a.copy()
    b[7, 9, 1] += np.float32(delta)
    want = psnr_closed(a, b)
    assert psnr(a, b) == pytest.approx(want, rel=1e-9) if math.isfinite(want) else psnr(a, b) == math.inf
    s = ssim(a, b)
    assert s == pytest.approx(ssim_brute(a, b), abs=1e-9) and s <= 1.0
    d = lpips(a, b)
    assert math.isfinite(d) and d >= 0
    if np.clip(b, 0, 1)[7, 9, 1] != a[7, 9, 1]:
        assert d > 0


def test_non_finite_pixels_are_clean_errors(stress_counts):
    a = np.zeros(SHAPE, np.float32)
    for bad in (np.nan, np.inf, -np.inf):
        b = a.copy()
        b[3, 4, 0] = bad
        stress_counts.add("metrics", non_finite=1)
        for fn in (psnr, ssim):
            with pytest.raises(InputError, match="NaN or infinite"):
                fn(a, b)


values = st.sampled_from([-1e30, -1.0, 0.0, 1e-30, 1e-7, 0.3, 0.5, 1.0 - 1e-7, 1.0, 2.0, 1e30])


@examples(25, 1500)
@given(hnp.arrays(np.float32, st.tuples(st.integers(1, 14), st.integers(1, 14), st.just(3)), elements=values),
       st.data())
def test_random_extreme_images(stress_counts, a, data):
    b = data.draw(hnp.arrays(np.float32, a.shape, elements=values))
    stress_counts.add("metrics", random=1)
    p = psnr(a, b)
    want = psnr_closed(a, b)
    assert (p == want == math.inf) or p == pytest.approx(want, rel=1e-12)
    s = ssim(a, b)
    assert math.isfinite(s) and -1.0 <= s <= 1.0 + 1e-12
    assert s == pytest.approx(ssim_brute(a, b), abs=1e-9)


@examples(4, 150)
@given(hnp.arrays(np.float32, (16, 20, 3), elements=values), hnp.arrays(np.float32, (16, 20, 3), elements=values))
def test_random_extreme_images_lpips(lpips, stress_counts, a, b):
    stress_counts.add("metrics", random_lpips=1)
    d = lpips(a, b)
    assert math.isfinite(d) and d >= -1e-7
    if np.array_equal(np.clip(a, 0, 1), np.clip(b, 0, 1)):
        assert abs(d) <= 1e-6
