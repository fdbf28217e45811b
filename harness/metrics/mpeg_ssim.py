"""SSIM and OM-SSIM of one plane exactly as mpeg-gsc-metrics v3.0 computes them (bit for bit).

Source: ``Metric::computeSSIM`` / ``Metric::computeMaskedSSIM`` in mpeg-gsc-metrics
(ISO/IEC, BSD), as vendored in github.com/little-little-point-cloud-group/gscem @
c4a0c1cae5693c5ef5697b62ca2e85af12fce36c, ``submodules/mpeg-gsc-metrics/source/metric.cpp``.
Written from reading that file; no code copied.

Per plane (values are doubles: float BT.709 YUV or the QMIV integer YUV), window w = 11×11
Gaussian, σ = 1.5, ``w[i][j] = exp(−(i² + j²)/(2σ²)) / Σ`` (i, j ∈ −5..5, the sum taken i-outer),
``C1 = (0.01·255)², C2 = (0.03·255)²`` — L = 255 hard-coded. For every pixel (no cropping)::

    μa = Σ_j Σ_i w[i][j]·Pa[y+j, x+i]                 (j = row offset outer, i = column inner)
    σa² = Σ_j Σ_i (w[i][j]·(Pa − μa))·(Pa − μa)         (second, centred pass; likewise σb², σab)
    SSIM(y, x) = ((2μa)μb + C1)(2σab + C2) / (((μa² + μb²) + C1)((σa² + σb²) + C2))

and the result is the running sum of the map in pixel order divided by the count. OM-SSIM weights
every tap by the mask m ∈ {0, 1}: ``μa = Σ (w·m)·Pa / Σ w·m``, ``σ² = Σ ((w·m)·d)·d / Σ w·m``; a
pixel whose ``Σ w·m < 0.5`` is skipped (metric.cpp: ``if ( maskSum < threshold ) { continue; }``,
``threshold = 0.5``); no pixel left → 1.0.

**Padding — the tool's quirks, copied exactly** (metric.cpp, "Pad edges"; the image P is the plane
with 5 px added on each side, tool rows are bottom-up, see below)::

    const int yt = std::min( std::max( y - halfWin, 0 ), srcY );        // y < 5: always 0
    const int yb = std::min( std::max( y - halfWin, 0 ), height - 1 );  // y < 5: always 0
    paddedImg1.set( x, bottomY + y, img1.get( x0, yb ) );               // rows after H-1 copy row 0
    paddedImg1.set( x, y, img1.get( srcX, y0 ) );                       // left: column min(5, W-1)
    paddedImg1.set( rightX + x, y, img1.get( width - 1 - x, y0 ) );     // right: mirror W-1, W-2, ...

So: the 5 rows before row 0 replicate row 0 (correct); the 5 rows after row H−1 are row 0 again
(not H−1); the 5 left columns are column 5 (not 0); the 5 right columns mirror the last five
columns. The column loop runs last, so corners follow the column rules with the row clamped.
The mask is padded the same way. The tool's buffers are OpenGL read-backs whose row 0 is the
*bottom* image row, so callers pass top-down arrays with ``rows_top_down=True`` and they are
flipped first (the padding is not up/down symmetric; the flip changes SSIM by ~1e-4 on photos).

Implementation: numba, row by row; for each output row the 121 taps are applied as whole-row
vector operations, so every pixel still sees the tool's sequence of roundings (same taps, same
order, no fused multiply-add, no reassociation) — bit-identical to a per-pixel loop, ~50× faster.
A reference's own moments (μa, σa²) are computed once (:func:`plane_stats`) and reused for every
image compared with it: each accumulator is a separate sum, so this changes no bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

WINDOW = 11
HALF = WINDOW // 2
SIGMA = 1.5
C1 = (0.01 * 255.0) * (0.01 * 255.0)
C2 = (0.03 * 255.0) * (0.03 * 255.0)
MASK_THRESHOLD = 0.5


def gaussian_window(size: int = WINDOW, sigma: float = SIGMA) -> np.ndarray:
    """``w[i + 5][j + 5] = exp(−(i² + j²)/(2σ²)) / Σ``; the sum runs i outer, j inner, as in the tool."""
    half = size // 2
    w = np.empty((size, size))
    total = 0.0
    for i in range(-half, half + 1):
        for j in range(-half, half + 1):
            v = math.exp(-(i * i + j * j) / (2 * sigma * sigma))
            w[i + half, j + half] = v
            total += v
    return w / total


_W = gaussian_window()


def pad_like_tool(plane: np.ndarray, half: int = HALF) -> np.ndarray:
    """The tool's padded plane (tool row order, see the module docstring), dtype kept."""
    h, w = plane.shape
    if w <= half or h < 1:  # tiny planes: the general index form (the tool reads out of bounds there)
        xs = np.clip(np.arange(w + 2 * half) - half, 0, w - 1)
        rows = np.concatenate([np.zeros(half, np.int64), np.arange(h), np.zeros(half, np.int64)])
        out = plane[rows][:, xs]
        clamped = np.clip(np.arange(h + 2 * half) - half, 0, h - 1)
        out[:, :half] = plane[clamped, min(half, w - 1)][:, None]
        out[:, w + half:] = plane[clamped][:, w - 1 - np.arange(half)]
        return np.ascontiguousarray(out)
    out = np.empty((h + 2 * half, w + 2 * half), plane.dtype)
    out[half:h + half, half:w + half] = plane
    out[:half, half:w + half] = plane[0]                  # rows before row 0: row 0
    out[h + half:, half:w + half] = plane[0]              # quirk: rows after row H-1 are row 0 again
    col = plane[:, half]                                  # quirk: left columns copy column 5
    out[half:h + half, :half] = col[:, None]
    out[:half, :half] = col[0]
    out[h + half:, :half] = col[h - 1]                    # corners: the column loop clamps rows
    right = plane[:, w - 1:w - 1 - half:-1]               # mirror: W-1, W-2, ..., W-5
    out[half:h + half, w + half:] = right
    out[:half, w + half:] = right[0]
    out[h + half:, w + half:] = right[h - 1]
    return out


@nb.njit(cache=True, fastmath=False)
def _moments(pa, w, h, width):
    """Per pixel of a padded plane: window mean μ and ``Σ (w·(P − μ))·(P − μ)`` (tool order), (h, width) each."""
    mu = np.zeros((h, width))
    s = np.zeros((h, width))
    for y in range(h):
        mu_y = mu[y]
        s_y = s[y]
        for j in range(WINDOW):
            ra = pa[y + j]
            for i in range(WINDOW):
                wt = w[i, j]
                for x in range(width):
                    mu_y[x] += wt * ra[x + i]
        for j in range(WINDOW):
            ra = pa[y + j]
            for i in range(WINDOW):
                wt = w[i, j]
                for x in range(width):
                    da = ra[x + i] - mu_y[x]
                    s_y[x] += wt * da * da
    return mu, s


@nb.njit(cache=True, fastmath=False)
def _ssim_sum(pa, mu_a_all, s_aa_all, pb, w, h, width):
    """(Σ SSIM over pixels in row-major tool order, count) of two padded planes, the first one's
    moments given (:func:`_moments`: each accumulator sums its taps in the same order as if both
    planes were filtered together, so the split changes no bit)."""
    total = 0.0
    count = 0
    mu_b = np.empty(width)
    s_bb = np.empty(width)
    s_ab = np.empty(width)
    for y in range(h):
        mu_a = mu_a_all[y]
        s_aa = s_aa_all[y]
        mu_b[:] = 0.0
        for j in range(WINDOW):
            rb = pb[y + j]
            for i in range(WINDOW):
                wt = w[i, j]
                for x in range(width):
                    mu_b[x] += wt * rb[x + i]
        s_bb[:] = 0.0
        s_ab[:] = 0.0
        for j in range(WINDOW):
            ra = pa[y + j]
            rb = pb[y + j]
            for i in range(WINDOW):
                wt = w[i, j]
                for x in range(width):
                    da = ra[x + i] - mu_a[x]
                    db = rb[x + i] - mu_b[x]
                    s_bb[x] += wt * db * db
                    s_ab[x] += wt * da * db
        for x in range(width):
            num = (2 * mu_a[x] * mu_b[x] + C1) * (2 * s_ab[x] + C2)
            den = (mu_a[x] * mu_a[x] + mu_b[x] * mu_b[x] + C1) * (s_aa[x] + s_bb[x] + C2)
            if den > 0:
                total += num / den
                count += 1
    return total, count


@nb.njit(cache=True, fastmath=False)
def _masked_ssim_sum(pa, pb, pm, w, h, width):
    """(Σ OM-SSIM over the pixels whose window mask weight reaches 0.5, their count)."""
    total = 0.0
    count = 0
    mu_a = np.empty(width)
    mu_b = np.empty(width)
    msum = np.empty(width)
    s_aa = np.empty(width)
    s_bb = np.empty(width)
    s_ab = np.empty(width)
    for y in range(h):
        mu_a[:] = 0.0
        mu_b[:] = 0.0
        msum[:] = 0.0
        for j in range(WINDOW):
            ra = pa[y + j]
            rb = pb[y + j]
            rm = pm[y + j]
            for i in range(WINDOW):
                wt = w[i, j]
                for x in range(width):
                    wm = wt * rm[x + i]
                    mu_a[x] += wm * ra[x + i]
                    mu_b[x] += wm * rb[x + i]
                    msum[x] += wm
        for x in range(width):  # dividing a skipped pixel too is harmless: it is never read
            mu_a[x] /= msum[x] if msum[x] >= MASK_THRESHOLD else 1.0
            mu_b[x] /= msum[x] if msum[x] >= MASK_THRESHOLD else 1.0
        s_aa[:] = 0.0
        s_bb[:] = 0.0
        s_ab[:] = 0.0
        for j in range(WINDOW):
            ra = pa[y + j]
            rb = pb[y + j]
            rm = pm[y + j]
            for i in range(WINDOW):
                wt = w[i, j]
                for x in range(width):
                    wm = wt * rm[x + i]
                    da = ra[x + i] - mu_a[x]
                    db = rb[x + i] - mu_b[x]
                    s_aa[x] += wm * da * da
                    s_bb[x] += wm * db * db
                    s_ab[x] += wm * da * db
        for x in range(width):
            if msum[x] < MASK_THRESHOLD:
                continue
            saa = s_aa[x] / msum[x]
            sbb = s_bb[x] / msum[x]
            sab = s_ab[x] / msum[x]
            num = (2 * mu_a[x] * mu_b[x] + C1) * (2 * sab + C2)
            den = (mu_a[x] * mu_a[x] + mu_b[x] * mu_b[x] + C1) * (saa + sbb + C2)
            if den > 0:
                total += num / den
                count += 1
    return total, count


@dataclass(frozen=True)
class PlaneStats:
    """One plane's side of its SSIM with any other plane: padded as the tool pads it, and its window
    moments (:func:`_moments`). Computed once per reference plane (:func:`plane_stats`)."""

    padded: np.ndarray
    mu: np.ndarray
    var: np.ndarray


def plane_stats(plane: np.ndarray) -> PlaneStats:
    """:class:`PlaneStats` of a (H, W) plane in tool row order (float64 values)."""
    h, w = plane.shape
    padded = pad_like_tool(np.ascontiguousarray(plane, np.float64))
    mu, var = _moments(padded, _W, h, w)
    return PlaneStats(padded, mu, var)


def ssim_yuv(a, b: np.ndarray, mask: np.ndarray | None = None) -> tuple[list[float], list[float] | None]:
    """Per-plane SSIM (and OM-SSIM with ``mask``) of two (H, W, 3) float64 images in tool row
    order; each plane and the mask are padded once for both. ``a`` may be given as its three planes'
    :class:`PlaneStats` (a reference measured against many images)."""
    stats = a if isinstance(a, (list, tuple)) else [plane_stats(a[..., c]) for c in range(3)]
    h, w = stats[0].mu.shape
    pm = None if mask is None else pad_like_tool((np.asarray(mask) != 0).astype(np.float64))
    full, om = [], ([] if mask is not None else None)
    for c in range(3):
        sa = stats[c]
        pb = pad_like_tool(np.ascontiguousarray(b[..., c], np.float64))
        total, count = _ssim_sum(sa.padded, sa.mu, sa.var, pb, _W, h, w)
        full.append(total / count if count > 0 else 1.0)
        if pm is not None:
            total, count = _masked_ssim_sum(sa.padded, pb, pm, _W, h, w)
            om.append(total / count if count > 0 else 1.0)
    return full, om
