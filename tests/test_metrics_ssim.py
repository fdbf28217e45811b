"""SSIM against a plain reference implementation (explicit 11x11 window loops) and scikit-image."""

import numpy as np
import pytest
import torch
from skimage import data
from skimage.metrics import structural_similarity

from harness.core.errors import InputError
from harness.metrics.ssim import blur_numpy, blur_torch, ssim, ssim_batch, ssim_map


def reference_ssim_map(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Textbook SSIM map of one channel, float64, 2-D Gaussian window, zero padding, loops over offsets."""
    r, sigma = 5, 1.5
    off = np.arange(-r, r + 1)
    g2 = np.exp(-(off[:, None] ** 2 + off[None, :] ** 2) / (2 * sigma**2))
    g2 /= g2.sum()
    h, w = x.shape
    px, py = np.pad(x, r), np.pad(y, r)
    mu_x, mu_y, exx, eyy, exy = (np.zeros((h, w)) for _ in range(5))
    for i in range(2 * r + 1):
        for j in range(2 * r + 1):
            sx, sy = px[i:i + h, j:j + w], py[i:i + h, j:j + w]
            mu_x += g2[i, j] * sx
            mu_y += g2[i, j] * sy
            exx += g2[i, j] * sx * sx
            eyy += g2[i, j] * sy * sy
            exy += g2[i, j] * sx * sy
    c1, c2 = 0.01**2, 0.03**2
    vx, vy, cxy = exx - mu_x**2, eyy - mu_y**2, exy - mu_x * mu_y
    return ((2 * mu_x * mu_y + c1) * (2 * cxy + c2)) / ((mu_x**2 + mu_y**2 + c1) * (vx + vy + c2))


def reference_ssim(a, b, border="zero"):
    a, b = np.clip(a.astype(np.float64), 0, 1), np.clip(b.astype(np.float64), 0, 1)
    maps = [reference_ssim_map(a[..., c], b[..., c]) for c in range(a.shape[2])]
    if border == "valid":
        maps = [m[5:-5, 5:-5] for m in maps]
    return float(np.mean([m.mean() for m in maps]))


def _real_pair():
    a = data.astronaut()[100:196, 150:278].astype(np.float32) / 255.0
    rng = np.random.default_rng(1)
    b = np.clip(a + rng.normal(0, 0.04, a.shape), 0, 1).astype(np.float32)
    return a, b


def _random_pair(seed):
    rng = np.random.default_rng(seed)
    a = rng.random((37, 53, 3), dtype=np.float32)
    b = np.clip(a + rng.normal(0, 0.2, a.shape), -0.1, 1.1).astype(np.float32)  # out-of-range: clamped
    return a, b


@pytest.mark.parametrize("pair", ["random0", "random1", "real"])
@pytest.mark.parametrize("border", ["zero", "valid"])
def test_agrees_with_plain_reference(pair, border):
    a, b = _real_pair() if pair == "real" else _random_pair(int(pair[-1]))
    assert ssim(a, b, border=border) == pytest.approx(reference_ssim(a, b, border), abs=1e-9)


def test_torch_conv_path_matches_plain_reference():
    a, b = _real_pair()
    x = torch.from_numpy(a.astype(np.float64)).permute(2, 0, 1)[None]
    y = torch.from_numpy(b.astype(np.float64)).permute(2, 0, 1)[None]
    got = ssim_map(x, y, blur=blur_torch).mean().item()
    assert got == pytest.approx(reference_ssim(a, b), abs=1e-9)
    stack = torch.rand(2, 3, 20, 30, dtype=torch.float64)
    taps = np.array([0.25, 0.5, 0.25])
    assert torch.allclose(blur_torch(stack, taps), blur_numpy(stack, taps), atol=1e-14)


@pytest.mark.parametrize("pair", ["random0", "real"])
def test_valid_border_agrees_with_scikit_image(pair):
    a, b = _real_pair() if pair == "real" else _random_pair(0)
    a, b = np.clip(a, 0, 1), np.clip(b, 0, 1)
    sk = structural_similarity(a.astype(np.float64), b.astype(np.float64), gaussian_weights=True, sigma=1.5,
                               use_sample_covariance=False, data_range=1, channel_axis=-1)
    assert ssim(a, b, border="valid") == pytest.approx(sk, abs=1e-5)
    assert abs(ssim(a, b, border="zero") - sk) > 1e-5  # the 3DGS convention really differs at the border


def test_identical_is_one_and_degradation_lowers_it():
    a, b = _real_pair()
    assert ssim(a, a) == 1.0
    assert ssim(a, b) < 0.99
    c = np.clip(a + np.random.default_rng(2).normal(0, 0.1, a.shape), 0, 1)
    assert ssim(a, c) < ssim(a, b)


def test_batch_matches_single():
    pairs = [_random_pair(0), _random_pair(1)]
    batch = ssim_batch(np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs]))
    assert batch == pytest.approx([ssim(*p) for p in pairs], abs=1e-12)


def test_bad_inputs():
    a, _ = _random_pair(0)
    with pytest.raises(InputError, match="sizes differ"):
        ssim(a, a[:-1])
    bad = a.copy()
    bad[3, 4, 1] = np.nan
    with pytest.raises(InputError, match="NaN"):
        ssim(a, bad)
    with pytest.raises(ValueError):
        ssim(a, a, border="reflect")
