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


@nb.njit(cache=True, nogil=True)
def window_any(flag, h, width):
    """``out[y, x] = any(flag[y:y + 11, x:x + 11])`` of a padded ``(h + 10, width + 10)`` flag plane
    (running box counts, rows then columns)."""
    rows = flag.shape[0]
    across = np.zeros((rows, width), np.int32)
    for r in range(rows):
        c = 0
        for i in range(WINDOW - 1):
            c += flag[r, i]
        for x in range(width):
            c += flag[r, x + WINDOW - 1]
            across[r, x] = c
            c -= flag[r, x]
    out = np.zeros((h, width), np.bool_)
    col = np.zeros(width, np.int32)
    for r in range(WINDOW - 1):
        col += across[r]
    for y in range(h):
        col += across[y + WINDOW - 1]
        for x in range(width):
            out[y, x] = col[x] > 0
        col -= across[y]
    return out


@nb.njit(cache=True, nogil=True)
def _differs(pa, pb):
    """Padded pixels where the planes differ, or where a value could make an equal window's SSIM
    other than exactly 1 (not finite, or so small or large that μ² leaves the normal range)."""
    out = np.empty(pa.shape, np.uint8)
    for y in range(pa.shape[0]):
        for x in range(pa.shape[1]):
            a = pa[y, x]
            m = abs(a)
            safe = a == pb[y, x] and (a == 0.0 or (m > 1e-100 and m < 1e100))
            out[y, x] = 0 if safe else 1
    return out


@nb.njit(cache=True, nogil=True)
def _runs(row):
    """Start and end (exclusive) of each run of True in a bool row, as an (n, 2) array."""
    n = 0
    inside = False
    for v in row:
        if v and not inside:
            n += 1
        inside = v
    out = np.empty((n, 2), np.int64)
    k = 0
    x = 0
    w = row.shape[0]
    while x < w:
        if row[x]:
            x1 = x
            while x1 < w and row[x1]:
                x1 += 1
            out[k, 0] = x
            out[k, 1] = x1
            k += 1
            x = x1
        else:
            x += 1
    return out


@nb.njit(cache=True, nogil=True)
def _mean_run(p, y, x0, x1, w, mu):
    """``mu[x − x0] = Σ_j Σ_i w[i, j]·P[y + j, x + i]`` for x in [x0, x1) (j outer, i inner)."""
    mu[:] = 0.0
    for j in range(WINDOW):
        r = p[y + j]
        for i in range(WINDOW):
            wt = w[i, j]
            for x in range(x0, x1):
                mu[x - x0] += wt * r[x + i]


@nb.njit(cache=True, nogil=True)
def _spread_run(p, mu, y, x0, x1, w, s):
    """``s[x − x0] = Σ_j Σ_i (w[i, j]·(P − μ))·(P − μ)`` over the window of x (the tool's order)."""
    s[:] = 0.0
    for j in range(WINDOW):
        r = p[y + j]
        for i in range(WINDOW):
            wt = w[i, j]
            for x in range(x0, x1):
                d = r[x + i] - mu[x - x0]
                s[x - x0] += wt * d * d


@nb.njit(cache=True, nogil=True)
def _full_run(pa, mu_a, s_aa, pb, y, x0, x1, w, out, ok):
    """SSIM of the pixels x0..x1 of row y (the tool's computeSSIM), the first plane's moments given."""
    n = x1 - x0
    mu_b = np.empty(n)
    _mean_run(pb, y, x0, x1, w, mu_b)
    s_bb = np.zeros(n)
    s_ab = np.zeros(n)
    for j in range(WINDOW):
        ra = pa[y + j]
        rb = pb[y + j]
        for i in range(WINDOW):
            wt = w[i, j]
            for x in range(n):
                da = ra[x0 + x + i] - mu_a[x]
                db = rb[x0 + x + i] - mu_b[x]
                s_bb[x] += wt * db * db
                s_ab[x] += wt * da * db
    for x in range(n):
        num = (2 * mu_a[x] * mu_b[x] + C1) * (2 * s_ab[x] + C2)
        den = (mu_a[x] * mu_a[x] + mu_b[x] * mu_b[x] + C1) * (s_aa[x] + s_bb[x] + C2)
        ok[x0 + x] = den > 0
        out[x0 + x] = num / den if den > 0 else 0.0


@nb.njit(cache=True, nogil=True)
def _mask_sum_run(pm, y, x0, x1, w, msum):
    """``msum[x − x0] = Σ_j Σ_i w[i, j]·M[y + j, x + i]`` (the tool's maskSum, its order)."""
    msum[:] = 0.0
    for j in range(WINDOW):
        rm = pm[y + j]
        for i in range(WINDOW):
            wt = w[i, j]
            for x in range(x0, x1):
                msum[x - x0] += wt * rm[x + i]


@nb.njit(cache=True, nogil=True)
def _masked_run(pa, pb, pm, y, x0, x1, w, out, ok):
    """OM-SSIM of the pixels x0..x1 of row y (the tool's computeMaskedSSIM); ``ok`` False where the
    window's mask weight is under 0.5 (skipped) or the denominator is not positive."""
    n = x1 - x0
    mu_a = np.zeros(n)
    mu_b = np.zeros(n)
    msum = np.zeros(n)
    for j in range(WINDOW):
        ra = pa[y + j]
        rb = pb[y + j]
        rm = pm[y + j]
        for i in range(WINDOW):
            wt = w[i, j]
            for x in range(n):
                wm = wt * rm[x0 + x + i]
                mu_a[x] += wm * ra[x0 + x + i]
                mu_b[x] += wm * rb[x0 + x + i]
                msum[x] += wm
    for x in range(n):  # dividing a skipped pixel too is harmless: it is never read
        mu_a[x] /= msum[x] if msum[x] >= MASK_THRESHOLD else 1.0
        mu_b[x] /= msum[x] if msum[x] >= MASK_THRESHOLD else 1.0
    s_aa = np.zeros(n)
    s_bb = np.zeros(n)
    s_ab = np.zeros(n)
    for j in range(WINDOW):
        ra = pa[y + j]
        rb = pb[y + j]
        rm = pm[y + j]
        for i in range(WINDOW):
            wt = w[i, j]
            for x in range(n):
                wm = wt * rm[x0 + x + i]
                da = ra[x0 + x + i] - mu_a[x]
                db = rb[x0 + x + i] - mu_b[x]
                s_aa[x] += wm * da * da
                s_bb[x] += wm * db * db
                s_ab[x] += wm * da * db
    for x in range(n):
        ok[x0 + x] = False
        out[x0 + x] = 0.0
        if msum[x] < MASK_THRESHOLD:
            continue
        saa = s_aa[x] / msum[x]
        sbb = s_bb[x] / msum[x]
        sab = s_ab[x] / msum[x]
        num = (2 * mu_a[x] * mu_b[x] + C1) * (2 * sab + C2)
        den = (mu_a[x] * mu_a[x] + mu_b[x] * mu_b[x] + C1) * (saa + sbb + C2)
        if den > 0:
            ok[x0 + x] = True
            out[x0 + x] = num / den


@nb.njit(cache=True, nogil=True, parallel=True)
def _ssim_maps(pa, mu_all, s_all, known, pb, pm, w, h, width, diff, near_mask, masked, full, full_ok, om,
               om_ok):
    """Per pixel (rows in parallel, each pixel's arithmetic the tool's): SSIM into ``full`` and, with
    a padded mask ``pm`` (``masked``; ``near_mask``: windows holding a masked-in pixel), OM-SSIM into
    ``om``; ``*_ok`` say which pixels count.

    Only pixels whose window differs (``diff``) are computed; the others are exactly 1 (equal
    windows: μa = μb, σa² = σb² = σab, so numerator and denominator are the same number). The first
    plane's moments are filled into ``mu_all``/``s_all`` where ``known`` is False, and read where
    it is True (a reference's moments, kept for the next image compared with it)."""
    for y in nb.prange(h):
        full_y, full_ok_y, diff_y = full[y], full_ok[y], diff[y]
        for x in range(width):
            full_y[x] = 1.0
            full_ok_y[x] = True
        runs = _runs(diff_y)
        for k in range(runs.shape[0]):
            x0, x1 = runs[k, 0], runs[k, 1]
            if not known[y, x0:x1].all():
                _mean_run(pa, y, x0, x1, w, mu_all[y, x0:x1])
                _spread_run(pa, mu_all[y, x0:x1], y, x0, x1, w, s_all[y, x0:x1])
                known[y, x0:x1] = True
            _full_run(pa, mu_all[y, x0:x1], s_all[y, x0:x1], pb, y, x0, x1, w, full_y, full_ok_y)
        if not masked:
            continue
        om_y, om_ok_y, near_y = om[y], om_ok[y], near_mask[y]
        for x in range(width):
            om_y[x] = 0.0
            om_ok_y[x] = False
        # a window without mask weighs 0 (skipped); an equal window weighing >= 0.5 is exactly 1
        runs = _runs(near_y)
        for k in range(runs.shape[0]):
            x0, x1 = runs[k, 0], runs[k, 1]
            msum = np.empty(x1 - x0)
            _mask_sum_run(pm, y, x0, x1, w, msum)
            for x in range(x0, x1):
                if msum[x - x0] >= MASK_THRESHOLD:
                    om_y[x] = 1.0
                    om_ok_y[x] = True
        runs = _runs(diff_y & near_y)
        for k in range(runs.shape[0]):
            _masked_run(pa, pb, pm, y, runs[k, 0], runs[k, 1], w, om_y, om_ok_y)


@nb.njit(cache=True, nogil=True)
def _ordered_sum(values, ok):
    """(Σ of the counted values in row-major pixel order, their count): the tool's running sum."""
    total = 0.0
    count = 0
    for y in range(values.shape[0]):
        for x in range(values.shape[1]):
            if ok[y, x]:
                total += values[y, x]
                count += 1
    return total, count


@nb.njit(cache=True, nogil=True)
def _fill_moments(p, w, h, width, mu, s):
    """Window mean and spread (:func:`_mean_run`, :func:`_spread_run`) of every pixel of a padded plane."""
    for y in range(h):
        _mean_run(p, y, 0, width, w, mu[y])
        _spread_run(p, mu[y], y, 0, width, w, s[y])


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
            _fill_moments(self.padded, _W, h, w, self.mu, self.var)
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
    pm = pad_like_tool((np.asarray(mask) != 0).astype(np.float64)) if masked else np.zeros((1, 1))
    near = window_any((pm != 0).view(np.uint8), h, w) if masked else np.zeros((1, 1), bool)
    maps = np.empty((h, w)), np.empty((h, w), bool), np.empty((h, w) if masked else (1, 1)), \
        np.empty((h, w) if masked else (1, 1), bool)
    full, om = [], ([] if masked else None)
    for c in range(3):
        sa = stats[c]
        pb = pad_like_tool(np.ascontiguousarray(b[..., c], np.float64))
        diff = window_any(_differs(sa.padded, pb), h, w)
        _ssim_maps(sa.padded, sa.mu, sa.var, sa.known, pb, pm, _W, h, w, diff, near, masked, *maps)
        total, count = _ordered_sum(maps[0], maps[1])
        full.append(total / count if count > 0 else 1.0)
        if masked:
            total, count = _ordered_sum(maps[2], maps[3])
            om.append(total / count if count > 0 else 1.0)
    return full, om
