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

Implementation (:mod:`.mpeg_ssim_kernels`): numba, runs of a row's pixels at a time, each tap applied
over the whole run, so every pixel still sees the tool's sequence of roundings (same taps, same
order, no fused multiply-add, no reassociation) — bit-identical to a per-pixel loop. Only pixels
whose window differs between the planes are computed (an equal window's SSIM is exactly 1, proof
there); a pruned scene's render differs from its source's in ~10 % of a luigi view. A reference's
own moments (μa, σa²) are computed where first needed and kept (:class:`PlaneStats`) for every
image compared with it: each accumulator is a separate sum, so this changes no bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from harness.metrics import mpeg_ssim_kernels as kernels
from harness.metrics.mpeg_ssim_kernels import C1, C2, MASK_THRESHOLD, WINDOW

HALF = WINDOW // 2
SIGMA = 1.5
__all__ = ["C1", "C2", "HALF", "MASK_THRESHOLD", "SIGMA", "WINDOW", "PlaneStats", "gaussian_window", "pad_like_tool",
           "plane_stats", "ssim_yuv"]


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


@dataclass(frozen=True)
class PlaneStats:
    """One plane's side of its SSIM with any other plane: padded as the tool pads it, and its window
    moments μ and ``Σ (w·(P − μ))·(P − μ)``, filled where first needed (``known``) and kept for the
    next plane compared with it (:func:`plane_stats`)."""

    padded: np.ndarray
    mu: np.ndarray
    var: np.ndarray
    known: np.ndarray

    def complete(self) -> PlaneStats:
        """Fill the moments of every pixel (the whole-plane form, e.g. to check the torch twin)."""
        if not self.known.all():
            h, w = self.mu.shape
            kernels.fill_moments(self.padded, _W, h, w, self.mu, self.var)
            self.known[:] = True
        return self


def plane_stats(plane: np.ndarray) -> PlaneStats:
    """:class:`PlaneStats` of a (H, W) plane in tool row order (float64 values), no moment filled yet."""
    h, w = plane.shape
    padded = pad_like_tool(np.ascontiguousarray(plane, np.float64))
    return PlaneStats(padded, np.zeros((h, w)), np.zeros((h, w)), np.zeros((h, w), bool))


def ssim_yuv(a, b: np.ndarray, mask: np.ndarray | None = None) -> tuple[list[float], list[float] | None]:
    """Per-plane SSIM (and OM-SSIM with ``mask``) of two (H, W, 3) float64 images in tool row
    order; each plane and the mask are padded once for both. ``a`` may be given as its three planes'
    :class:`PlaneStats` (a reference measured against many images)."""
    stats = a if isinstance(a, (list, tuple)) else [plane_stats(a[..., c]) for c in range(3)]
    h, w = stats[0].mu.shape
    masked = mask is not None
    if masked:
        pm = pad_like_tool((np.asarray(mask) != 0).astype(np.float64))
        count = kernels.window_count((pm != 0).view(np.uint8), h, w)
        om_maps = np.empty((h, w)), np.empty((h, w), bool)
    else:
        pm, count, om_maps = np.zeros((1, 1)), np.zeros((1, 1), np.int32), (np.empty((1, 1)), np.empty((1, 1), bool))
    full_maps = np.empty((h, w)), np.empty((h, w), bool)
    full, om = [], ([] if masked else None)
    for c in range(3):
        sa = stats[c]
        pb = pad_like_tool(np.ascontiguousarray(b[..., c], np.float64))
        diff = kernels.window_count(kernels.differs(sa.padded, pb), h, w) > 0
        kernels.ssim_maps(sa.padded, sa.mu, sa.var, sa.known, pb, pm, _W, diff, count, masked, *full_maps, *om_maps)
        total, n = kernels.ordered_sum(*full_maps)
        full.append(total / n if n > 0 else 1.0)
        if masked:
            total, n = kernels.ordered_sum(*om_maps)
            om.append(total / n if n > 0 else 1.0)
    return full, om
