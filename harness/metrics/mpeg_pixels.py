"""The tool's per-pixel conversions in one numba pass each (:mod:`.mpeg` states the formulas).

Every value is the one numpy computes from the same formula: the same IEEE operations in the same
order on the same types (float32 product and round half away from zero for the 8-bit quantisation;
double sums of float32 coefficients rounded to float32 for the default YUV; int64 fixed point with
arithmetic shifts for the QMIV YUV), without numpy's temporaries.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True)
def quantize_f32(p):
    """8-bit RGB of float32 ``(H, W, 3)`` colours: ``clamp(round(c · 255f), 0, 255)``, the product in
    float32, round half away from zero (the fraction ``v − trunc(v)`` is exact), NaN → 0."""
    h, w, _ = p.shape
    out = np.empty((h, w, 3), np.uint8)
    scale = np.float32(255.0)
    for y in range(h):
        for x in range(w):
            for c in range(3):
                v = p[y, x, c] * scale
                if v != v or v <= 0:  # NaN, or a value whose rounding is at most 0
                    out[y, x, c] = 0
                elif v >= 255:  # rounds to 255 or more (inf included)
                    out[y, x, c] = 255
                else:
                    t = np.trunc(v)
                    out[y, x, c] = np.uint8(t + (1 if v - t >= 0.5 else 0))
    return out


@nb.njit(cache=True, nogil=True)
def yuv_default(rgb, coef, rounding):
    """Image::getYuv of integer RGB ``(H, W, 3)``: float64 ``(H, W, 3)``, channel k rounded to float32
    where ``rounding[k]``; ``Y = (c00 R + c01 G) + c02 B``, chroma ``+ 128`` last."""
    h, w, _ = rgb.shape
    out = np.empty((h, w, 3))
    for y in range(h):
        for x in range(w):
            r, g, b = np.float64(rgb[y, x, 0]), np.float64(rgb[y, x, 1]), np.float64(rgb[y, x, 2])
            v0 = coef[0, 0] * r + coef[0, 1] * g + coef[0, 2] * b
            v1 = coef[1, 0] * r + coef[1, 1] * g + coef[1, 2] * b + 128.0
            v2 = coef[2, 0] * r + coef[2, 1] * g + coef[2, 2] * b + 128.0
            out[y, x, 0] = np.float64(np.float32(v0)) if rounding[0] else v0
            out[y, x, 1] = np.float64(np.float32(v1)) if rounding[1] else v1
            out[y, x, 2] = np.float64(np.float32(v2)) if rounding[2] else v2
    return out


@nb.njit(cache=True, nogil=True)
def _clip255(v):
    return 0 if v < 0 else (255 if v > 255 else v)


@nb.njit(cache=True, nogil=True)
def yuv_qmiv(rgb):
    """Image::getYuvQmiv of integer RGB ``(H, W, 3)``: int64 ``(H, W, 3)``, 16-bit fixed point, floor
    shift, clamped to 0..255."""
    h, w, _ = rgb.shape
    out = np.empty((h, w, 3), np.int64)
    for y in range(h):
        for x in range(w):
            r, g, b = np.int64(rgb[y, x, 0]), np.int64(rgb[y, x, 1]), np.int64(rgb[y, x, 2])
            out[y, x, 0] = _clip255((13933 * r + 46871 * g + 4732 * b + 32768) >> 16)
            out[y, x, 1] = _clip255(((-7509 * r - 25259 * g + (b << 15) + 32768) >> 16) + 128)
            out[y, x, 2] = _clip255((((r << 15) - 29763 * g - 3005 * b + 32768) >> 16) + 128)
    return out


@nb.njit(cache=True, nogil=True)
def square_sums_int(a, b, mask):
    """Per channel Σ (a − b)² of integer pictures ``(H, W, 3)``, over all pixels and over those where
    ``mask``: two float64 ``(3,)``, each the exact int64 sum (the tool's running double sum of these
    integers is exact too, whatever the order)."""
    full = np.zeros(3, np.int64)
    part = np.zeros(3, np.int64)
    for y in range(a.shape[0]):
        for x in range(a.shape[1]):
            for c in range(3):
                d = np.int64(a[y, x, c]) - np.int64(b[y, x, c])
                full[c] += d * d
                if mask[y, x]:
                    part[c] += d * d
    return full.astype(np.float64), part.astype(np.float64)


@nb.njit(cache=True, nogil=True)
def square_sums_float(a, b, mask):
    """Per channel Σ (a − b)² of float64 pictures ``(H, W, 3)``, over all pixels and over those where
    ``mask``, each a running double sum in row-major pixel order (the tool's)."""
    full = np.zeros(3)
    part = np.zeros(3)
    for y in range(a.shape[0]):
        for x in range(a.shape[1]):
            for c in range(3):
                d = a[y, x, c] - b[y, x, c]
                full[c] += d * d
                if mask[y, x]:
                    part[c] += d * d
    return full, part
