"""IV-SSIM (harness.metrics.ivssim, PMBB xIVSSIM as mpeg-gsc-metrics calls it) against the
independent transcription in tests/mpeg_reference.py (== on every pair), plus the rules one by one:
identity, the global colour shift and its rounding, the ±2 px search, the block count, tiny images."""

from __future__ import annotations

import math

import numpy as np
import pytest

from harness.metrics import ivssim, mpeg
from tests import mpeg_reference as ref


def _images(h, w, seed, kind):
    rng = np.random.default_rng(seed)
    a = rng.integers(0, 256, (h, w, 3)).astype(np.uint8)
    if kind == "noise":
        b = a.astype(int) + rng.integers(-12, 13, a.shape) + int(rng.integers(-6, 7))
    elif kind == "shift":
        b = np.roll(a, (1, -2), axis=(0, 1)).astype(int)
    elif kind == "render":  # an object on black, partly removed
        a = np.zeros((h, w, 3), np.uint8)
        a[h // 4:3 * h // 4, w // 5:4 * w // 5] = rng.integers(0, 256, (3 * h // 4 - h // 4, 4 * w // 5 - w // 5, 3))
        b = a.astype(int)
        b[h // 3:h // 2] = 0
    else:
        b = rng.integers(0, 256, a.shape)
    return a, np.clip(b, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("kind", ["noise", "shift", "render", "independent"])
@pytest.mark.parametrize("shape", [(8, 8), (13, 21), (40, 64), (67, 45)])
def test_equal_to_the_transcription(shape, kind):
    a, b = _images(*shape, seed=shape[0] + shape[1], kind=kind)
    got = mpeg.tool_metrics(a, b, None, ssim=False, om=False)
    want = ref.iv_ssim(a[::-1], b[::-1])  # the tool's bottom-up rows
    assert (got["rgb_ivssim"], got["yuv_ivssim"]) == want
    assert mpeg.tool_metrics(a, b, None, qmiv=True, ssim=False, om=False)["yuv_ivssim"] == want[1]  # mode-free


def test_identical_images_score_exactly_one():
    a, _ = _images(24, 32, 1, "noise")
    r = mpeg.tool_metrics(a, a, None, ssim=False, om=False)
    assert r["rgb_ivssim"] == r["yuv_ivssim"] == 1.0


def test_a_global_shift_within_three_levels_is_forgiven():
    a = np.random.default_rng(2).integers(10, 240, (32, 32, 3)).astype(np.uint8)
    r2 = ivssim.iv_ssim_planes(a, a + 2, ivssim.EQUAL_WEIGHTS)   # g = 2: R~ = (A + 2) - 2 = A
    r5 = ivssim.iv_ssim_planes(a, a + 5, ivssim.EQUAL_WEIGHTS)   # g clipped to 3
    assert r2 == 1.0 and r5 < 1.0
    assert ivssim.global_colour_shift(a, a + 5).tolist() == [3, 3, 3]
    assert ivssim.global_colour_shift(a + 5, a).tolist() == [-3, -3, -3]


def test_global_shift_rounds_half_away_from_zero():
    a = np.full((8, 8, 3), 100, np.uint8)
    up, down = a.copy(), a.copy()
    up[:4, :, 0] = 101    # mean difference +0.5 -> +1 (std::round), not 0 (banker's)
    down[:4, :, 0] = 99   # -0.5 -> -1
    assert ivssim.global_colour_shift(a, up).tolist() == [1, 0, 0]
    assert ivssim.global_colour_shift(a, down).tolist() == [-1, 0, 0]


def test_the_search_forgives_small_displacements_only():
    a, _ = _images(48, 48, 3, "noise")
    moved2 = np.roll(a, 2, axis=1)
    moved4 = np.roll(a, 4, axis=1)
    iv2 = ivssim.iv_ssim_planes(a, moved2, ivssim.EQUAL_WEIGHTS)
    iv4 = ivssim.iv_ssim_planes(a, moved4, ivssim.EQUAL_WEIGHTS)
    assert iv2 > 0.9 > iv4  # a 2 px move stays within the ±2 search (up to the wrapped edge columns)


@pytest.mark.parametrize("length", range(8, 80))
def test_block_count_is_the_number_of_blocks_inside(length):
    assert ivssim.block_count(length) == len(range(0, length - ivssim.BLOCK + 1, ivssim.STRIDE))
    assert ivssim.block_count(length) == ref._num_blocks(length, 8, 4)


def test_pictures_without_a_block_give_nan():
    a, b = _images(7, 30, 4, "noise")
    assert math.isnan(ivssim.iv_ssim_planes(a, b, ivssim.EQUAL_WEIGHTS))


def test_ycbcr_is_pmbbs_integer_bt709():
    """ConvertRGB2YCbCr_I32's coefficients: xRnd(2^16 · m) of calcMatrixRGB2YCbCr(0.2126, 0.7152, 0.0722)."""
    kr, kg, kb = 0.2126, 0.7152, 0.0722
    sb, sr = 0.5 / (kb - 1.0), 0.5 / (kr - 1.0)

    def rnd(v):
        v *= 65536.0
        return int(v + 0.5) if v >= 0 else -int(-v + 0.5)

    assert [rnd(kr), rnd(kg), rnd(kb), rnd(sb * kr), rnd(sb * kg), rnd(sr * kg), rnd(sr * kb)] == \
        [13933, 46871, 4732, -7509, -25259, -29763, -3005]
    rgb = np.random.default_rng(5).integers(0, 256, (9, 9, 3)).astype(np.uint8)
    assert np.array_equal(mpeg.yuv_qmiv(rgb), ref.yuv_qmiv(rgb))
