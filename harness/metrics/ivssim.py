"""IV-SSIM of mpeg-gsc-metrics v3.0 (PMBB ``xIVSSIM``, block-averaged), number for number.

Sources (BSD), read, no code copied: mpeg-gsc-metrics ``source/metric.cpp`` (``Metric::computeIVSSIM``)
at github.com/little-little-point-cloud-group/gscem @ c4a0c1cae569…, and the PMBB library it vendors
(``dependencies/pmbb-*``: QMIV v2.0's file set, STD kernels only), github.com/jstankowski/QMIV @
a601648f8a48 ``libs/pmbb-ivqm/src/``: ``xSSIM.cpp`` (``xIVSSIM::calcPicIVSSIM``, ``xSSIM::xCalcPicSSIM``,
``xCalcNumBlocks``), ``xStructSimSTD.cpp`` (``CalcBlckAvg``), ``xGlobClrDiff.cpp``, ``xShftCompPic.cpp``,
``xCorrespPixelShift.cpp`` (``xFindBestPixelWithinBlock``); ``libs/pmbb-core/src/xKBNS.h``,
``xPixelOpsSTD.cpp`` (``ExtendMargin``), ``xColorSpaceSTD.cpp`` (``ConvertRGB2YCbCr_I32``).

The tool calls ``calcPicIVSSIM(Tst = A, Ref = B)`` with A the source render and B the processed one,
8-bit planes in its bottom-up row order, ``setStructSimParams(BlockAveraged, -, 8, 4)``, search range 2::

    g_c   = clip(round(Σ (B_c − A_c) / (W·H)), −3, 3)       c = 0, 1, 2; round half away from zero (the
                                                           build has no SSE4.2: std::round); Σ in int32;
                                                           3 = round(0.01f · 255f)
    R̃     = shift(R = B, T = A, s = +g)                     T̃ = shift(R = A, T = B, s = −g)
    shift(R, T, s)(p) = clip(R(p + d*) − s, 0, 255),  d* = first argmin over dy = −2..2 (outer),
                        dx = −2..2 (inner) of Σ_c w_c (T_c(p) + s_c − R_c(p + d))²  (R edge-replicated)
    S_c(X, Y) = Σ_blocks SSIM_8×8 / n_blocks                8×8 blocks at stride 4 from the top-left,
                                                           inside the picture; n = xCalcNumBlocks
    SSIM_8×8  = (2μxμy + C1)/(μx² + μy² + C1) · (2σxy + C2)/(σx² + σy² + C2)
                μ = ΣX/64, σ² = ΣX²/64 − μ², σxy = ΣXY/64 − μxμy (integer sums, then double);
                C1 = (0.01·255)², C2 = (0.03·255)²
    IV-SSIM   = min(Σ_c w_c S_c(A, R̃), Σ_c w_c S_c(B, T̃)) / Σ_c w_c

Block values are summed per block row, then over rows, with Kahan–Babuška–Neumaier summation
(``xKBNS``), as the tool does. Two variants, both in either tool mode (``--computeQmiv`` does not
change them): **RGB** (w = 1:1:1 for search and average, ``c_EqualCmpWeights``) and **YCbCr**
(w = 4:1:1, ``c_DefaultCmpWeights``) on PMBB's integer BT.709 (:func:`harness.metrics.mpeg.yuv_qmiv`,
the same ``ConvertRGB2YCbCr_I32`` arithmetic). A picture narrower or lower than 8 pixels has no
block; the tool then divides by a zero (or negative) count: we return NaN.
"""

from __future__ import annotations

import numba as nb
import numpy as np

BLOCK = 8
STRIDE = 4
SEARCH = 2
#: PMBB's ExtendMargin pads each picture by its margin (4 in the tool; the search reads 2)
MARGIN = 4
#: c_DefaultUnntcbCoef · 255 rounded (xRoundFltToInt32(0.01f * 255.0f))
MAX_SHIFT = 3
C1 = (0.01 * 255.0) * (0.01 * 255.0)
C2 = (0.03 * 255.0) * (0.03 * 255.0)
EQUAL_WEIGHTS = (1, 1, 1)
DEFAULT_WEIGHTS = (4, 1, 1)


def block_count(length: int) -> int:
    """``xSSIM::xCalcNumBlocks(length, 8, 4)`` (its power-of-two branch)."""
    full = length >> 3
    return ((full - 1) << 1) + ((length - (full << 3)) >> 2) + 1


def global_colour_shift(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``xGlobClrDiff::CalcGlobalColorDiff(B, A)``: per component ``round(Σ(B − A)/area)`` in [−3, 3].

    The int32 sum wraps as in the tool (only for pictures beyond 8.4 Mpx of one-sided differences);
    rounding half away from zero of the exact quotient equals ``std::round`` of the double quotient
    (a quotient of two integers < 2^32 is never within one double ulp of a half without being one)."""
    h, w, _ = a.shape
    out = np.empty(3, np.int64)
    for c in range(3):
        s = int(b[..., c].sum(dtype=np.int64)) - int(a[..., c].sum(dtype=np.int64))  # Σ(B − A), exactly
        s = (s + (1 << 31)) % (1 << 32) - (1 << 31)  # int32 accumulator
        q = h * w
        r = (2 * abs(s) + q) // (2 * q)
        out[c] = min(MAX_SHIFT, r) * (1 if s >= 0 else -1)
    return out


@nb.njit(cache=True, nogil=True)
def _planar(img):
    """An integer ``(H, W, 3)`` picture as int32 planes ``(3, H, W)``."""
    h, w, _ = img.shape
    out = np.empty((3, h, w), np.int32)
    for y in range(h):
        for x in range(w):
            for c in range(3):
                out[c, y, x] = img[y, x, c]
    return out


@nb.njit(cache=True, nogil=True)
def _shift_row(ref, tst, shift, weights, y, out):
    """Row y of :func:`_shift_compensate`."""
    h, w = tst.shape[1], tst.shape[2]
    w0, w1, w2 = weights[0], weights[1], weights[2]
    exact = w0 > 0 and w1 > 0 and w2 > 0
    for x in range(w):
        a0, a1, a2 = tst[0, y, x] + shift[0], tst[1, y, x] + shift[1], tst[2, y, x] + shift[2]
        by, bx = y, x
        if not (exact and a0 == ref[0, y, x] and a1 == ref[1, y, x] and a2 == ref[2, y, x]):
            best = np.int32(2147483647)
            for dy in range(-SEARCH, SEARCH + 1):
                yy = min(max(y + dy, 0), h - 1)
                for dx in range(-SEARCH, SEARCH + 1):
                    xx = min(max(x + dx, 0), w - 1)
                    d0, d1, d2 = a0 - ref[0, yy, xx], a1 - ref[1, yy, xx], a2 - ref[2, yy, xx]
                    err = d0 * d0 * w0 + d1 * d1 * w1 + d2 * d2 * w2
                    if err < best:
                        best, by, bx = err, yy, xx
        for c in range(3):
            v = ref[c, by, bx] - shift[c]
            out[c, y, x] = 0 if v < 0 else (255 if v > 255 else v)


@nb.njit(cache=True, nogil=True, parallel=True)
def _shift_compensate(ref, tst, shift, weights):
    """``xShftCompPic::xGenShftCompPic`` on planar int32 pictures ``(3, H, W)``, planar out, rows in
    parallel (every pixel is its own search). ``ref`` is read at clamped coordinates: PMBB's
    ExtendMargin replicates the edges by MARGIN ≥ SEARCH pixels. Per pixel the 25 candidates are
    visited in the tool's order (dy outer, dx inner) and a strictly smaller error replaces the best,
    so the first minimum wins, as in ``xFindBestPixelWithinBlock``. Where the centre candidate's
    error is 0 (positive weights: every component matches) the search is skipped: whichever
    candidate wins then has error 0 too, holds the same values, gives the same output."""
    out = np.empty(tst.shape, np.int32)
    for y in nb.prange(tst.shape[1]):
        _shift_row(ref, tst, shift, weights, np.int64(y), out)  # a signed row: y + dy may be negative
    return out


@nb.njit(cache=True, nogil=True)
def _kbns_add(s, c, v):
    t = s + v
    if abs(s) >= abs(v):
        c += (s - t) + v
    else:
        c += (v - t) + s
    return t, c


@nb.njit(cache=True, nogil=True, parallel=True)
def _block_values(tst, ref, c1, c2):
    """``CalcBlckAvg`` with the luminance term of every 8×8 block (stride 4), block rows in parallel."""
    h, w = tst.shape
    rows, cols = (h - BLOCK) // STRIDE + 1, (w - BLOCK) // STRIDE + 1
    out = np.empty((rows, cols))
    inv = 1.0 / 64.0
    for by in nb.prange(rows):
        y = by * STRIDE
        for bx in range(cols):
            x = bx * STRIDE
            sr = np.int64(0)
            st = np.int64(0)
            srr = np.int64(0)
            stt = np.int64(0)
            srt = np.int64(0)
            for j in range(BLOCK):
                for i in range(BLOCK):
                    r = np.int64(ref[y + j, x + i])
                    t = np.int64(tst[y + j, x + i])
                    sr += r
                    st += t
                    srr += r * r
                    stt += t * t
                    srt += r * t
            avg_r = sr * inv
            avg_t = st * inv
            var_r = srr * inv - avg_r * avg_r
            var_t = stt * inv - avg_t * avg_t
            cov = srt * inv - avg_r * avg_t
            lum = (2 * avg_r * avg_t + c1) / (avg_r * avg_r + avg_t * avg_t + c1)
            cs = (2 * cov + c2) / (var_r + var_t + c2)
            out[by, bx] = lum * cs
    return out


@nb.njit(cache=True, nogil=True)
def _block_ssim_sum(tst, ref, c1, c2):
    """Σ over the blocks (:func:`_block_values`) with KBNS per block row, then KBNS over the row sums
    (``xKBNS::Accumulate`` starts from the first row's sum): in order, whatever the thread count."""
    values = _block_values(tst, ref, c1, c2)
    total = 0.0
    comp = 0.0
    for by in range(values.shape[0]):
        rs = 0.0
        rc = 0.0
        for bx in range(values.shape[1]):
            rs, rc = _kbns_add(rs, rc, values[by, bx])
        row = rs + rc
        if by == 0:
            total = row
        else:
            total, comp = _kbns_add(total, comp, row)
    return total + comp


def _component_ssim(tst: np.ndarray, ref: np.ndarray) -> float:
    """Block-averaged SSIM of two int32 planes."""
    h, w = tst.shape
    n = block_count(h) * block_count(w)
    total = _block_ssim_sum(tst, ref, C1, C2)
    return total / n if n > 0 else float("nan")


def _shifted(ref: np.ndarray, tst: np.ndarray, shift: np.ndarray, weights) -> np.ndarray:
    """``ref`` shift-compensated onto ``tst`` (both planar int32 ``(3, H, W)``), planar."""
    return _shift_compensate(ref, tst, np.asarray(shift, np.int32), np.asarray(weights, np.int32))


def iv_ssim_planes(a: np.ndarray, b: np.ndarray, weights) -> float:
    """``xIVSSIM::calcPicIVSSIM(Tst = a, Ref = b)`` of two (H, W, 3) integer pictures in 0..255,
    tool row order, with component weights ``weights`` for the search and the average."""
    a, b = np.asarray(a), np.asarray(b)
    h, w, _ = a.shape
    if h < BLOCK or w < BLOCK:
        return float("nan")
    g = global_colour_shift(a, b)
    pa, pb = _planar(a), _planar(b)
    ref_scp = _shifted(pb, pa, g, weights)
    tst_scp = _shifted(pa, pb, -g, weights)
    t2r = [_component_ssim(pa[c], ref_scp[c]) for c in range(3)]
    r2t = [_component_ssim(pb[c], tst_scp[c]) for c in range(3)]
    inv = 1.0 / float(sum(weights))  # (SSIMs · weights).getSum(): ((s0·w0 + s1·w1) + s2·w2) + 0·0
    s_t2r = (t2r[0] * weights[0] + t2r[1] * weights[1] + t2r[2] * weights[2]) * inv
    s_r2t = (r2t[0] * weights[0] + r2t[1] * weights[1] + r2t[2] * weights[2]) * inv
    return min(s_t2r, s_r2t)
