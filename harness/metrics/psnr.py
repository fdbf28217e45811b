"""PSNR on [0, 1] images, its aggregation, and the MPEG-style YUV (BT.709) PSNR.

PSNR = 10 log10(1 / MSE), MSE over all pixels and channels of the [0, 1]-clamped float images
(float64 accumulation). Identical images (MSE = 0) give ``+inf``; :func:`summarize_psnr` reports
them as a count and averages only the finite values.

YUV-PSNR (our reading of the MPEG metric tools' report): RGB in [0, 1] is converted with the
full-range BT.709 matrix (Kr = 0.2126, Kb = 0.0722)::

    Y = Kr R + (1 - Kr - Kb) G + Kb B,  U = (B - Y) / (2 (1 - Kb)) + 0.5,  V = (R - Y) / (2 (1 - Kr)) + 0.5

on the full 4:4:4 grid in floating point (no chroma subsampling, no 8/10-bit quantisation, no
limited-range scaling), PSNR per plane with peak 1, and the combination
YUV-PSNR = (6 PSNR_Y + PSNR_U + PSNR_V) / 8 of MPEG's *video* common test conditions. This is not
what MPEG's Gaussian-splat metric tool reports (8-bit renders, 1:1:1 on MSE, float BT.709 with +128
chroma): that is the ``mpeg`` metric set, :mod:`harness.metrics.mpeg`.
"""

from __future__ import annotations

import math

import numpy as np

from harness.metrics.images import as_image, check_same_size

KR, KB = 0.2126, 0.0722


def mse(a: np.ndarray, b: np.ndarray) -> float:
    """Mean squared error of the [0, 1]-clamped images over all pixels and channels."""
    d = np.clip(np.asarray(a, dtype=np.float64), 0, 1) - np.clip(np.asarray(b, dtype=np.float64), 0, 1)
    return float(np.mean(d * d))


def psnr_from_mse(m: float, peak: float = 1.0) -> float:
    """10 log10(peak^2 / m); ``inf`` when ``m == 0``."""
    return math.inf if m == 0.0 else 10.0 * math.log10(peak * peak / m)


def psnr(a, b) -> float:
    """PSNR (dB) of two images ``(H, W, 3)``; ``inf`` when they are identical after clamping."""
    a, b = as_image(a, "first image"), as_image(b, "second image")
    check_same_size(a, b)
    return psnr_from_mse(mse(a, b))


def rgb_to_yuv709(rgb: np.ndarray) -> np.ndarray:
    """Full-range BT.709 Y'CbCr of RGB ``(..., 3)`` in [0, 1] (Cb, Cr offset to 0.5), float64."""
    rgb = np.asarray(rgb, dtype=np.float64)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    y = KR * r + (1.0 - KR - KB) * g + KB * b
    u = (b - y) / (2.0 * (1.0 - KB)) + 0.5
    v = (r - y) / (2.0 * (1.0 - KR)) + 0.5
    return np.stack([y, u, v], axis=-1)


def yuv_psnr(a, b) -> dict:
    """``{"psnr_y", "psnr_u", "psnr_v", "psnr_yuv"}`` of two RGB images (see module docstring)."""
    a, b = as_image(a, "first image"), as_image(b, "second image")
    check_same_size(a, b)
    ya, yb = rgb_to_yuv709(np.clip(a, 0, 1)), rgb_to_yuv709(np.clip(b, 0, 1))
    d = ya - yb
    per = [psnr_from_mse(float(np.mean(d[..., k] ** 2))) for k in range(3)]
    return {"psnr_y": per[0], "psnr_u": per[1], "psnr_v": per[2],
            "psnr_yuv": (6.0 * per[0] + per[1] + per[2]) / 8.0}


def summarize_psnr(values) -> dict:
    """``{"mean", "count", "n_inf"}``: mean over the finite PSNRs, with the identical pairs counted apart.

    ``mean`` is ``nan`` when every value is infinite (nothing finite to average).
    """
    v = np.asarray(list(values), dtype=np.float64)
    if np.isnan(v).any() or np.isneginf(v).any():
        raise ValueError("PSNR values must be finite or +inf")
    finite = v[np.isfinite(v)]
    return {"mean": float(finite.mean()) if finite.size else math.nan,
            "count": int(finite.size), "n_inf": int(v.size - finite.size)}
