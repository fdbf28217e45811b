"""PSNR, YUV-PSNR (BT.709) and PSNR aggregation against independent truth."""

import math

import numpy as np
import pytest
from skimage import data
from skimage.metrics import peak_signal_noise_ratio

from harness.core.errors import InputError
from harness.metrics.psnr import psnr, rgb_to_yuv709, summarize_psnr, yuv_psnr


def test_identical_is_inf():
    a = data.astronaut().astype(np.float32) / 255
    assert psnr(a, a) == math.inf
    assert all(v == math.inf for v in yuv_psnr(a, a).values())


def test_matches_scikit_image_and_closed_form():
    rng = np.random.default_rng(0)
    a = data.astronaut()[:64, :80].astype(np.float32) / 255
    b = np.clip(a + rng.normal(0, 0.05, a.shape), 0, 1).astype(np.float32)
    sk = peak_signal_noise_ratio(a.astype(np.float64), b.astype(np.float64), data_range=1)
    assert psnr(a, b) == pytest.approx(sk, abs=1e-9)
    c = np.full((10, 10, 3), 0.5, np.float32)
    assert psnr(c, c + np.float32(0.1)) == pytest.approx(20.0, abs=1e-5)  # MSE 0.01 -> 20 dB


def test_clamps_to_unit_range():
    a = np.zeros((8, 8, 3), np.float32)
    b = a.copy()
    b[0, 0, 0] = -5.0  # clamps to 0: identical
    assert psnr(a, b) == math.inf
    b[0, 0, 0] = 3.0  # clamps to 1: one squared error of 1 over 192 values
    assert psnr(a, b) == pytest.approx(10 * math.log10(192), abs=1e-9)


def test_yuv709_coefficients():
    # BT.709 full range: white -> (1, .5, .5); primaries give the published Y weights, U/V extremes +-0.5
    yuv = rgb_to_yuv709(np.array([[1, 1, 1], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float))
    assert yuv[0] == pytest.approx([1, 0.5, 0.5])
    assert yuv[:, 0] == pytest.approx([1, 0.2126, 0.7152, 0.0722])
    assert yuv[3, 1] == pytest.approx(1.0) and yuv[1, 2] == pytest.approx(1.0)


def test_yuv_psnr_on_known_differences():
    grey = np.full((16, 16, 3), 0.4, np.float32)
    r = yuv_psnr(grey, grey + np.float32(0.1))  # grey shift: chroma unchanged
    assert r["psnr_u"] == math.inf and r["psnr_v"] == math.inf
    assert r["psnr_y"] == pytest.approx(20.0, abs=1e-4)
    red = grey.copy()
    red[..., 0] += 0.1  # V moves by exactly 0.5 * 0.1, Y by 0.2126 * 0.1, U by -0.2126 * 0.1 / 1.8556
    r = yuv_psnr(grey, red)
    assert r["psnr_v"] == pytest.approx(-20 * math.log10(0.05), abs=1e-4)
    assert r["psnr_y"] == pytest.approx(-20 * math.log10(0.02126), abs=1e-4)
    assert r["psnr_u"] == pytest.approx(-20 * math.log10(0.02126 / 1.8556), abs=1e-4)
    assert r["psnr_yuv"] == pytest.approx((6 * r["psnr_y"] + r["psnr_u"] + r["psnr_v"]) / 8)


def test_summary_counts_inf_apart():
    s = summarize_psnr([30.0, math.inf, 40.0, math.inf])
    assert s == {"mean": 35.0, "count": 2, "n_inf": 2}
    assert math.isnan(summarize_psnr([math.inf])["mean"])
    with pytest.raises(ValueError):
        summarize_psnr([math.nan])


def test_bad_inputs():
    a = np.zeros((8, 8, 3), np.float32)
    with pytest.raises(InputError, match="sizes differ"):
        psnr(a, np.zeros((8, 9, 3), np.float32))
    b = a.copy()
    b[1, 2, 0] = np.inf
    with pytest.raises(InputError, match="infinite"):
        psnr(a, b)
    with pytest.raises(InputError, match="not an image"):
        psnr(a, np.zeros((8, 8, 5), np.float32))
