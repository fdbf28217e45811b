"""Contact sheet: coverage definition on hand-made images, grid layout and labels."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from harness.views.contact_sheet import coverage, to_uint8, write_contact_sheet


def test_coverage_counts_pixels_that_differ_from_the_background():
    bg = (0.2, 0.4, 0.6)
    img = np.tile(np.array(bg, np.float32), (4, 4, 1))
    img[0, 0, 2] += 0.5          # one channel differs
    img[1, 1] = (0.0, 0.0, 0.0)  # black content over a non-black background
    img[2, 2, 0] += 0.5 / 255    # below one 8-bit step: background
    assert coverage(img, bg) == pytest.approx(2 / 16)
    alpha = np.zeros((4, 4))
    alpha[:, 0] = 0.5
    assert coverage(img, bg, alpha=alpha) == pytest.approx(4 / 16)


def test_to_uint8_clamps_without_gamma():
    np.testing.assert_array_equal(to_uint8(np.array([[[-1.0, 0.5, 2.0]]])), [[[0, 128, 255]]])


def _odd_render(seed: int = 0) -> np.ndarray:
    """A render with values outside [0, 1], exact half steps, NaN, ±inf and −0 in various channels."""
    img = np.random.default_rng(seed).normal(0.3, 0.6, (37, 53, 3)).astype(np.float32)
    img[0, :6] = [[np.nan, 0, 0], [np.inf, 0, 0], [-np.inf, 1, 0], [-0.0, -0.0, -0.0], [np.nan, 5, 0],
                  [0.5 / 255, 1.5 / 255, 254.5 / 255]]
    return img


@pytest.mark.parametrize("seed", [0, 1])
def test_to_uint8_is_the_clamp_of_nan_to_num_rounded_half_up(seed):
    img = _odd_render(seed)
    want = (np.clip(np.nan_to_num(img), 0.0, 1.0) * np.float32(255.0) + np.float32(0.5)).astype(np.uint8)
    np.testing.assert_array_equal(to_uint8(img), want)


@pytest.mark.parametrize("bg", [(0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (0.2, 0.5, 0.7)])
def test_coverage_is_the_share_of_pixels_whose_largest_channel_difference_passes(bg):
    img = _odd_render()
    diff = np.abs(img - np.asarray(bg, np.float32)).max(axis=2)  # NaN in a channel: NaN, not counted
    assert coverage(img, bg) == float(np.mean(diff > 1.0 / 255.0))


def test_sheet_grid(tmp_path):
    imgs = [np.full((30, 40, 3), v, np.float32) for v in (0.0, 0.5, 1.0)]
    covs = write_contact_sheet(imgs, ["a", "b", "c"], tmp_path / "s.png", thumb_longest=20, columns=2)
    assert covs == [0.0, 1.0, 1.0]
    sheet = np.asarray(Image.open(tmp_path / "s.png"))
    assert sheet.shape[0] > 2 * 15 and sheet.shape[1] > 2 * 20  # 2 rows × 2 columns of 20×15 thumbnails
    assert sheet[4 + 5, 4 + 20 + 4 + 5].tolist() == [128, 128, 128]  # second thumbnail, mid-grey
    with pytest.raises(ValueError):
        write_contact_sheet(imgs, ["a"], tmp_path / "t.png")
