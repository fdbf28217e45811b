"""Test-only reference: a line-by-line numpy re-statement of mpeg-gsc-metrics v3.0's image arithmetic.

Copied, as test code, from the project's research notes (/work/notes/mpeg_ref.py, our own reading of
the tool's metric.cpp / image.hpp at github.com/little-little-point-cloud-group/gscem @ c4a0c1ca…,
checked there bit for bit against a compiled C++ transcription on 44 image pairs). It shares no code
with harness.metrics.mpeg: plain per-tap numpy loops in the tool's order, np.cumsum for running sums.
IV-SSIM (``iv_ssim``) re-states PMBB's xIVSSIM as metric.cpp calls it, from QMIV v2.0's sources
(github.com/jstankowski/QMIV @ a601648f8a48, the file set the tool vendors): vectorised numpy with exact
integer block sums, sharing nothing with harness.metrics.ivssim (numba loops); both were checked equal
(0.0 difference) to a locally compiled PMBB v2.0 driver on 42 synthetic pairs and 12 GL renders.
"""

from __future__ import annotations

import math

import numpy as np

PEAK_U8 = 255.0
CAP = 999.99

# ----------------------------------------------------------------------------------------------
# colour conversions (util/image.hpp)
# ----------------------------------------------------------------------------------------------
_F = np.float32
_Y = [float(_F(0.2126)), float(_F(0.7152)), float(_F(0.0722))]
_U = [float(_F(0.1146)), float(_F(0.3854)), float(_F(0.5000))]
_V = [float(_F(0.5000)), float(_F(0.4542)), float(_F(0.0458))]


def yuv_default(rgb: np.ndarray, f32_round=(True, True, True)) -> np.ndarray:
    """Image::getYuv: float32 BT.709 coefficients, double arithmetic, +128 chroma, NO clamp/round,
    result rounded to float32 (returned through glm::vec3), then used as double.
    f32_round: per-channel switch of that float32 rounding (see YUV_ROUNDING below)."""
    r, g, b = (rgb[..., i].astype(np.float64) for i in range(3))
    y = _Y[0] * r + _Y[1] * g + _Y[2] * b          # exact in double (products/sums need < 40 bits)
    u = -_U[0] * r - _U[1] * g + _U[2] * b + 128.0
    v = _V[0] * r - _V[1] * g - _V[2] * b + 128.0
    out = [c.astype(np.float32).astype(np.float64) if rnd else c for c, rnd in zip((y, u, v), f32_round)]
    return np.stack(out, -1)


# How the default-mode YUV reaches the *MSE* loop in a compiled tool:
#  "float32": as written in the source (Y,U,V rounded to float32). clang -O3, g++ -O0/-O1, g++ -fno-tree-slp-vectorize.
#  "gcc-o3" : g++ 11/12 at -O3 (the tool's Linux build: CMake Release) SLP-vectorises the MSE loop and drops the
#             double->float->double round trip for Y and U (V keeps it). The SSIM path keeps float32 for all three.
#  Difference between the two: |dMSE| ~ 1e-6 relative, |dPSNR| <~ 1e-5 dB. QMIV mode is unaffected (integers).
YUV_ROUNDING = {"float32": (True, True, True), "gcc-o3": (False, False, True)}


def yuv_qmiv(rgb: np.ndarray) -> np.ndarray:
    """Image::getYuvQmiv: 16-bit fixed-point BT.709 (= PMBB ConvertRGB2YCbCr_I32), floor shift, clamp 0..255."""
    r, g, b = (rgb[..., i].astype(np.int64) for i in range(3))
    y = np.clip((13933 * r + 46871 * g + 4732 * b + 32768) >> 16, 0, 255)
    u = np.clip(((-7509 * r - 25259 * g + (b << 15) + 32768) >> 16) + 128, 0, 255)
    v = np.clip((((r << 15) - 29763 * g - 3005 * b + 32768) >> 16) + 128, 0, 255)
    return np.stack([y, u, v], -1).astype(np.float64)


# ----------------------------------------------------------------------------------------------
# helpers reproducing the C++ reduction order
# ----------------------------------------------------------------------------------------------
def _seqsum(a: np.ndarray) -> float:
    """Naive left-to-right double sum (what `acc += x` in a C++ loop gives)."""
    a = np.ascontiguousarray(a, dtype=np.float64).ravel()
    return float(np.cumsum(a)[-1]) if a.size else 0.0


def _psnr(peak2: float, mse: float) -> float:
    # glm::min(dvec3(999.99), 10*log10(peak2/mse)); mse==0 -> +inf -> 999.99
    if mse == 0.0:
        return CAP
    return min(CAP, 10.0 * math.log10(peak2 / mse))


def _psnr_of_mean(peak2: float, mses) -> float:
    m = (mses[0] + mses[1] + mses[2]) / 3.0
    return min(CAP, 10.0 * math.log10(peak2 / m)) if m > 0 else CAP


def gaussian_window(size: int = 11, sigma: float = 1.5) -> np.ndarray:
    """generateGaussianWindow: w[i][j] = exp(-(i*i+j*j)/(2*sigma*sigma)) / sum  (i,j in -5..5, summed i-outer)."""
    half = size // 2
    w = np.empty((size, size))
    s = 0.0
    for i in range(-half, half + 1):
        for j in range(-half, half + 1):
            val = math.exp(-(i * i + j * j) / (2 * sigma * sigma))
            w[i + half, j + half] = val
            s += val
    return w / s


_GW = gaussian_window()


def _pad_like_tool(img: np.ndarray, half: int = 5) -> np.ndarray:
    """Padding of Metric::computeSSIM / computeMaskedSSIM (img is indexed [y, x], y = tool row).

    interior          P[y+5, x+5]      = I[y, x]
    top rows y<5      P[y, 5+x]        = I[0, x]               (edge replicate, x clamped)
    bottom rows       P[H+5+y, 5+x]    = I[0, x]   <-- QUIRK: row 0 again, not row H-1
    left cols x<5     P[y, x]          = I[clamp(y-5), min(5, W-1)]   <-- QUIRK: column 5, not column 0
    right cols        P[y, W+5+x]      = I[clamp(y-5), W-1-x]  (mirror incl. edge: W-1, W-2, ...)
    (the column loop runs last over all padded rows, so the four corners follow the column rules
     with a correctly clamped row index.)
    """
    H, W = img.shape
    P = np.zeros((H + 2 * half, W + 2 * half), dtype=img.dtype)
    P[half:half + H, half:half + W] = img
    src_x = min(half, W - 1)
    src_y = min(half, H - 1)
    xs = np.clip(np.arange(W + 2 * half) - half, 0, W - 1)
    for y in range(half):
        yt = min(max(y - half, 0), src_y)          # always 0
        yb = min(max(y - half, 0), H - 1)          # always 0
        P[y, :] = img[yt, xs]
        P[H + half + y, :] = img[yb, xs]
    ys = np.clip(np.arange(H + 2 * half) - half, 0, H - 1)
    for x in range(half):
        P[:, x] = img[ys, src_x]
        P[:, W + half + x] = img[ys, W - 1 - x]
    return P


def ssim_plane(a: np.ndarray, b: np.ndarray) -> float:
    """Metric::computeSSIM on one plane (double values, L=255 always)."""
    H, W = a.shape
    c1 = (0.01 * 255.0) * (0.01 * 255.0)
    c2 = (0.03 * 255.0) * (0.03 * 255.0)
    P1, P2 = _pad_like_tool(a), _pad_like_tool(b)
    mu1 = np.zeros((H, W)); mu2 = np.zeros((H, W))
    for j in range(11):              # j = y offset (outer), i = x offset (inner), weight = w[i][j]
        for i in range(11):
            w = _GW[i, j]
            mu1 += w * P1[j:j + H, i:i + W]
            mu2 += w * P2[j:j + H, i:i + W]
    s11 = np.zeros((H, W)); s22 = np.zeros((H, W)); s12 = np.zeros((H, W))
    for j in range(11):
        for i in range(11):
            w = _GW[i, j]
            d1 = P1[j:j + H, i:i + W] - mu1
            d2 = P2[j:j + H, i:i + W] - mu2
            s11 += w * d1 * d1
            s22 += w * d2 * d2
            s12 += w * d1 * d2
    num = (2 * mu1 * mu2 + c1) * (2 * s12 + c2)
    den = (mu1 * mu1 + mu2 * mu2 + c1) * (s11 + s22 + c2)
    ok = den > 0                       # always true (c1, c2 > 0)
    n = int(ok.sum())
    return _seqsum((num / den)[ok]) / n if n > 0 else 1.0


def ssim_plane_masked(a: np.ndarray, b: np.ndarray, m: np.ndarray) -> float:
    """Metric::computeMaskedSSIM (OM-SSIM). m: 0/1 array (same padding quirks applied to it)."""
    H, W = a.shape
    c1 = (0.01 * 255.0) * (0.01 * 255.0)
    c2 = (0.03 * 255.0) * (0.03 * 255.0)
    P1, P2, PM = _pad_like_tool(a), _pad_like_tool(b), _pad_like_tool(m.astype(np.float64))
    mu1 = np.zeros((H, W)); mu2 = np.zeros((H, W)); msum = np.zeros((H, W))
    for j in range(11):
        for i in range(11):
            w = _GW[i, j]
            mv = PM[j:j + H, i:i + W]
            mu1 += w * mv * P1[j:j + H, i:i + W]
            mu2 += w * mv * P2[j:j + H, i:i + W]
            msum += w * mv
    ok = ~(msum < 0.5)                 # windows with weighted mask coverage < 0.5 are skipped
    with np.errstate(divide="ignore", invalid="ignore"):
        mu1 = mu1 / msum
        mu2 = mu2 / msum
        s11 = np.zeros((H, W)); s22 = np.zeros((H, W)); s12 = np.zeros((H, W))
        for j in range(11):
            for i in range(11):
                w = _GW[i, j]
                mv = PM[j:j + H, i:i + W]
                d1 = P1[j:j + H, i:i + W] - mu1
                d2 = P2[j:j + H, i:i + W] - mu2
                s11 += w * mv * d1 * d1
                s22 += w * mv * d2 * d2
                s12 += w * mv * d1 * d2
        s11 /= msum; s22 /= msum; s12 /= msum
        num = (2 * mu1 * mu2 + c1) * (2 * s12 + c2)
        den = (mu1 * mu1 + mu2 * mu2 + c1) * (s11 + s22 + c2)
    ok &= den > 0
    n = int(ok.sum())
    return _seqsum((num / den)[ok]) / n if n > 0 else 1.0


def _sep_filter(P: np.ndarray, H: int, W: int) -> np.ndarray:
    """sum_{j,i} g[j] g[i] P[y+j, x+i] via two 11-tap passes (g = normalised 1-D Gaussian, sigma 1.5)."""
    t = np.zeros((P.shape[0], W))
    for i in range(11):
        t += _G1[i] * P[:, i:i + W]
    o = np.zeros((H, W))
    for j in range(11):
        o += _G1[j] * t[j:j + H]
    return o


_G1 = np.exp(-(np.arange(11) - 5.0) ** 2 / (2 * 1.5 * 1.5)); _G1 /= _G1.sum()


def ssim_plane_fast(a, b, m=None) -> float:
    """Same formulas as ssim_plane / ssim_plane_masked, separable filtering and E[x^2]-mu^2 variances
    (~10x faster; differs from the tool by ~1e-13, not bit-exact; mask threshold compared the same way)."""
    H, W = a.shape
    c1 = (0.01 * 255.0) * (0.01 * 255.0)
    c2 = (0.03 * 255.0) * (0.03 * 255.0)
    P1, P2 = _pad_like_tool(a), _pad_like_tool(b)
    PM = np.ones_like(P1) if m is None else _pad_like_tool(m.astype(np.float64))
    S = _sep_filter(PM, H, W)
    with np.errstate(divide="ignore", invalid="ignore"):
        mu1 = _sep_filter(PM * P1, H, W) / S
        mu2 = _sep_filter(PM * P2, H, W) / S
        s11 = _sep_filter(PM * P1 * P1, H, W) / S - mu1 * mu1
        s22 = _sep_filter(PM * P2 * P2, H, W) / S - mu2 * mu2
        s12 = _sep_filter(PM * P1 * P2, H, W) / S - mu1 * mu2
        val = ((2 * mu1 * mu2 + c1) * (2 * s12 + c2)) / ((mu1 * mu1 + mu2 * mu2 + c1) * (s11 + s22 + c2))
    ok = np.ones((H, W), bool) if m is None else ~(S < 0.5)
    n = int(ok.sum())
    return float(val[ok].sum()) / n if n > 0 else 1.0


# ----------------------------------------------------------------------------------------------
# IV-SSIM (PMBB xIVSSIM, block-averaged 8x8 / stride 4, search range 2, margin 4)
# ----------------------------------------------------------------------------------------------
def _kbns(values) -> float:
    s = 0.0; c = 0.0
    for v in values:
        t = s + v
        c += ((s - t) + v) if abs(s) >= abs(v) else ((v - t) + s)
        s = t
    return s + c


def _kbns_rows(cols: np.ndarray) -> np.ndarray:
    """KBNS along axis 1, vectorised over rows (cols: [rows, n])."""
    s = np.zeros(cols.shape[0]); c = np.zeros(cols.shape[0])
    for k in range(cols.shape[1]):
        v = cols[:, k]
        t = s + v
        c += np.where(np.abs(s) >= np.abs(v), (s - t) + v, (v - t) + s)
        s = t
    return s + c


def _shift_comp(ref: np.ndarray, tst: np.ndarray, gcs: np.ndarray, wts, sr: int = 2, margin: int = 4) -> np.ndarray:
    """xShftCompPic::xGenShftCompRow (planar): for each tst pixel find best ref pixel in a (2sr+1)^2
    window (y outer, x inner, strict '<' => first minimum), error = sum_c w_c*(tst_c+gcs_c-ref_c)^2,
    output clip(ref[best]-gcs, 0, 255). ref is read with `margin` edge-replicated pixels (xPicP::extend)."""
    H, W, _ = ref.shape
    R = np.pad(ref, ((margin, margin), (margin, margin), (0, 0)), mode="edge").astype(np.int32)
    cur = [tst[..., c].astype(np.int32) + np.int32(gcs[c]) for c in range(3)]
    best_err = np.full((H, W), np.iinfo(np.int32).max, np.int32)
    best_k = np.zeros((H, W), np.int32)
    offs = [(dy, dx) for dy in range(-sr, sr + 1) for dx in range(-sr, sr + 1)]
    for k, (dy, dx) in enumerate(offs):
        err = np.zeros((H, W), np.int32)
        for c in range(3):
            d = cur[c] - R[margin + dy:margin + dy + H, margin + dx:margin + dx + W, c]
            err += np.int32(wts[c]) * d * d
        upd = err < best_err
        best_k[upd] = k
        np.minimum(best_err, err, out=best_err)
    oy = np.array([o[0] for o in offs])[best_k]; ox = np.array([o[1] for o in offs])[best_k]
    yy, xx = np.mgrid[0:H, 0:W]
    best = R[margin + yy + oy, margin + xx + ox].astype(np.int64)
    return np.clip(best - gcs[None, None, :3], 0, 255)


def _block_ssim_cmp(tst: np.ndarray, ref: np.ndarray, bs: int = 8, stride: int = 4) -> float:
    """xSSIM::xCalcCmpSSIM in BlockAveraged mode with CalcL=true (xStructSimSTD::CalcBlckAvg)."""
    H, W = tst.shape
    c1 = (0.01 * 255.0) * (0.01 * 255.0)  # xPow2(c_K1<flt64> * MaxValue)
    c2 = (0.03 * 255.0) * (0.03 * 255.0)
    ys = np.arange(0, H - bs + 1, stride); xs = np.arange(0, W - bs + 1, stride)
    T = tst.astype(np.int64); R = ref.astype(np.int64)

    def bsum(a):  # exact integer block sums at (ys, xs)
        ci = np.pad(a, ((1, 0), (1, 0))).cumsum(0).cumsum(1)
        return (ci[ys[:, None] + bs, xs[None, :] + bs] - ci[ys[:, None], xs[None, :] + bs]
                - ci[ys[:, None] + bs, xs[None, :]] + ci[ys[:, None], xs[None, :]])

    inv = 1.0 / (bs * bs)
    avg_r = bsum(R) * inv; avg_t = bsum(T) * inv
    var_r = bsum(R * R) * inv - avg_r * avg_r
    var_t = bsum(T * T) * inv - avg_t * avg_t
    cov = bsum(R * T) * inv - avg_r * avg_t
    L = (2 * avg_r * avg_t + c1) / (avg_r * avg_r + avg_t * avg_t + c1)
    CS = (2 * cov + c2) / (var_r + var_t + c2)
    total = _kbns(_kbns_rows(L * CS).tolist()) if (len(ys) and len(xs)) else 0.0
    n_act = _num_blocks(H, bs, stride) * _num_blocks(W, bs, stride)
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(np.float64(total) / np.float64(n_act))   # images < 8 px: 0/0 -> nan (as the tool)


def _num_blocks(length: int, bs: int, stride: int) -> int:
    """xSSIM::xCalcNumBlocks, power-of-two branch (bs=8, stride=4)."""
    lb, ls = bs.bit_length() - 1, stride.bit_length() - 1
    n1 = length >> lb
    rem = length - (n1 << lb)
    return ((n1 - 1) << (lb - ls)) + (rem >> ls) + 1


def _ivssim_pair(A: np.ndarray, B: np.ndarray, wts) -> float:
    """xIVSSIM::calcPicIVSSIM(Tst=A, Ref=B) with component weights wts for search and averaging."""
    H, W, _ = A.shape
    # xGlobClrDiff::CalcGlobalColorDiff(Ref, Tst): sum(B - A) / area, std::round, clip +-round(0.01f*255f)=3
    sd = (B.astype(np.int64) - A.astype(np.int64)).reshape(-1, 3).sum(0)   # NB: tool sums in int32
    avg = sd.astype(np.float64) / float(W * H)
    gcs = np.sign(avg) * np.floor(np.abs(avg) + 0.5)                      # std::round (half away)
    gcs = np.clip(gcs, -3, 3).astype(np.int64)
    ref_scp = _shift_comp(B, A, gcs, wts)      # DstRef from (Ref=B, Tst=A, +gcs)
    tst_scp = _shift_comp(A, B, -gcs, wts)     # DstTst from (Ref=A, Tst=B, -gcs)
    t2r = [_block_ssim_cmp(A[..., c], ref_scp[..., c]) for c in range(3)]
    r2t = [_block_ssim_cmp(B[..., c], tst_scp[..., c]) for c in range(3)]
    inv = 1.0 / float(sum(wts))
    s_t2r = (((t2r[0] * wts[0] + t2r[1] * wts[1]) + t2r[2] * wts[2]) + 0.0) * inv
    s_r2t = (((r2t[0] * wts[0] + r2t[1] * wts[1]) + r2t[2] * wts[2]) + 0.0) * inv
    return min(s_t2r, s_r2t)


def iv_ssim(A_rgb: np.ndarray, B_rgb: np.ndarray):
    """(rgbIvSsim, yuvIvSsim) as Metric::computeIVSSIM for uint8 images (bitDepth 8)."""
    rgb = _ivssim_pair(A_rgb, B_rgb, (1, 1, 1))
    ya = yuv_qmiv(A_rgb).astype(np.int64); yb = yuv_qmiv(B_rgb).astype(np.int64)  # PMBB I32 BT.709
    yuv = _ivssim_pair(ya, yb, (4, 1, 1))
    return rgb, yuv


# ----------------------------------------------------------------------------------------------
# main entry
# ----------------------------------------------------------------------------------------------
def mpeg_metrics(ref_uint8_rgb, test_uint8_rgb, mask=None, qmiv=False, *,
                 rows_top_down=True, compute_om=True, compute_ssim=True, compute_ivssim=True,
                 yuv_rounding="float32", exact=True) -> dict:
    """Metric::compute(imageA=ref, imageB=test, mask) for one view, uint8 RGB (H, W, 3).

    mask: None -> the tool's maskless overload (all-ones mask: OM == full-frame, occupancy 100).
          else boolean/0-1/uint8 array (H, W); nonzero = occupied (tool: union of src/dec occupancy maps).
    qmiv: False = MPEG default (float BT.709, PSNR of mean MSE); True = --computeQmiv=1.
    yuv_rounding: "float32" (source semantics, default) or "gcc-o3" (bit-exact to a GCC -O3 build), see YUV_ROUNDING.
    exact: True = SSIM/OM-SSIM with the tool's 121-step summation order (bit-exact, slow: ~30 s per 1080p view);
           False = separable filtering (~1e-13 from the tool, several times faster).
    """
    A = np.asarray(ref_uint8_rgb)[..., :3]
    B = np.asarray(test_uint8_rgb)[..., :3]
    assert A.dtype == np.uint8 and B.dtype == np.uint8 and A.shape == B.shape
    H, W, _ = A.shape
    M = np.ones((H, W), np.uint8) if mask is None else (np.asarray(mask) != 0).astype(np.uint8)
    if M.ndim == 3:
        M = M[..., 0]
    if rows_top_down:                      # tool buffers are bottom-up (OpenGL)
        A, B, M = A[::-1], B[::-1], M[::-1]
    A = np.ascontiguousarray(A); B = np.ascontiguousarray(B); M = np.ascontiguousarray(M)
    peak2 = PEAK_U8 * PEAK_U8
    size = H * W
    if qmiv:
        yA, yB = yuv_qmiv(A), yuv_qmiv(B)
        dyuv = (yA - yB).reshape(-1, 3)
    else:
        yA, yB = yuv_default(A), yuv_default(B)                       # SSIM path: always float32-rounded
        rnd = YUV_ROUNDING[yuv_rounding]
        dyuv = (yuv_default(A, rnd) - yuv_default(B, rnd)).reshape(-1, 3)   # MSE / OM-MSE path
    drgb = (A.astype(np.float64) - B.astype(np.float64)).reshape(-1, 3)
    mse_rgb = [_seqsum(drgb[:, c] * drgb[:, c]) / size for c in range(3)]
    mse_yuv = [_seqsum(dyuv[:, c] * dyuv[:, c]) / size for c in range(3)]
    r = {}
    r["mse_rgb"] = mse_rgb
    r["psnr_rgb"] = [_psnr(peak2, m) for m in mse_rgb]
    r["mse_yuv"] = mse_yuv
    r["psnr_yuv"] = [_psnr(peak2, m) for m in mse_yuv]
    if qmiv:
        r["psnr_rgb_avg"] = (r["psnr_rgb"][0] + r["psnr_rgb"][1] + r["psnr_rgb"][2]) / 3.0
        r["psnr_yuv_avg"] = (4.0 * r["psnr_yuv"][0] + r["psnr_yuv"][1] + r["psnr_yuv"][2]) / 6.0
    else:
        r["psnr_rgb_avg"] = _psnr_of_mean(peak2, mse_rgb)
        r["psnr_yuv_avg"] = _psnr_of_mean(peak2, mse_yuv)
    # OM-PSNR (fields stay 0.0 when the mask is empty -- and still enter the per-view average!)
    for k in ("mse_rgb_om", "psnr_rgb_om", "mse_yuv_om", "psnr_yuv_om"):
        r[k] = [0.0, 0.0, 0.0]
    r["psnr_rgb_om_avg"] = r["psnr_yuv_om_avg"] = r["occupancy"] = 0.0
    sel = M.ravel() != 0
    n_valid = int(sel.sum())
    if compute_om and n_valid > 0:
        r["mse_rgb_om"] = [_seqsum(drgb[sel, c] * drgb[sel, c]) / n_valid for c in range(3)]
        r["mse_yuv_om"] = [_seqsum(dyuv[sel, c] * dyuv[sel, c]) / n_valid for c in range(3)]
        r["psnr_rgb_om"] = [_psnr(peak2, m) for m in r["mse_rgb_om"]]
        r["psnr_yuv_om"] = [_psnr(peak2, m) for m in r["mse_yuv_om"]]
        if qmiv:
            p = r["psnr_rgb_om"]; r["psnr_rgb_om_avg"] = (p[0] + p[1] + p[2]) / 3.0
            p = r["psnr_yuv_om"]; r["psnr_yuv_om_avg"] = (4.0 * p[0] + p[1] + p[2]) / 6.0
        else:
            r["psnr_rgb_om_avg"] = _psnr_of_mean(peak2, r["mse_rgb_om"])
            r["psnr_yuv_om_avg"] = _psnr_of_mean(peak2, r["mse_yuv_om"])
        r["occupancy"] = 100.0 * n_valid / size
    r["ssim"] = [0.0, 0.0, 0.0]; r["ssim_avg"] = 0.0
    r["ssim_om"] = [0.0, 0.0, 0.0]; r["ssim_om_avg"] = 0.0
    if compute_ssim:
        ssim_full = ssim_plane if exact else (lambda x, y: ssim_plane_fast(x, y))
        ssim_om = ssim_plane_masked if exact else ssim_plane_fast
        r["ssim"] = [ssim_full(yA[..., c], yB[..., c]) for c in range(3)]
        s = r["ssim"]
        r["ssim_avg"] = (4.0 * s[0] + s[1] + s[2]) / 6.0 if qmiv else (s[0] + s[1] + s[2]) / 3.0
        if compute_om:   # NB: computed even when the mask is empty (then returns 1.0 per channel)
            r["ssim_om"] = [ssim_om(yA[..., c], yB[..., c], M) for c in range(3)]
            s = r["ssim_om"]
            r["ssim_om_avg"] = (4.0 * s[0] + s[1] + s[2]) / 6.0 if qmiv else (s[0] + s[1] + s[2]) / 3.0
    r["rgb_ivssim"] = r["yuv_ivssim"] = 0.0
    if compute_ivssim:
        r["rgb_ivssim"], r["yuv_ivssim"] = iv_ssim(A, B)
    return r


def average_views(results: list[dict]) -> dict:
    """Metric::getAverage: plain arithmetic mean of every field over all (frame, view) results,
    i.e. PSNRs are averaged in dB (not via mean MSE); OM fields of views with empty masks count as 0."""
    out = {}
    for k in results[0]:
        vals = [r[k] for r in results]
        if isinstance(vals[0], list):
            acc = [0.0, 0.0, 0.0]
            for v in vals:
                acc = [acc[i] + v[i] for i in range(3)]
            out[k] = [a / len(vals) for a in acc]
        else:
            acc = 0.0
            for v in vals:
                acc += v
            out[k] = acc / len(vals)
    return out


def quantize_render_to_u8(rgb_float: np.ndarray) -> np.ndarray:
    """Image<uint8_t>::from(): c*255.f in float32, std::round (half away from zero), clamp [0,255].
    Input: linear float colour already composited on BLACK (the tool never adds a background)."""
    p = (np.asarray(rgb_float, np.float32) * np.float32(255.0)).astype(np.float64)
    rnd = np.where(p >= 0, np.floor(p + 0.5), np.ceil(p - 0.5))
    return np.clip(rnd, 0, 255).astype(np.uint8)


# ----------------------------------------------------------------------------------------------
# viewpoints the tool places itself (util/viewpoints.hpp Viewpoints::create, util/camera.hpp
# Camera::setLookAt/viewMat, glm::lookAt), float32 as in the tool, line by line
# ----------------------------------------------------------------------------------------------
def _f32(*v):
    return np.array(v, np.float32)


def _normalize(v):                      # glm::normalize: v * inversesqrt(dot(v, v))
    return v * (np.float32(1.0) / np.sqrt(np.dot(v, v)))


def _lookat_rh(eye, center, up):        # glm::lookAt (right-handed): rows s, u, -f
    f = _normalize(center - eye)
    s = _normalize(np.cross(f, up))
    u = np.cross(s, f)
    m = np.eye(4, dtype=np.float32)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[0, 3], m[1, 3], m[2, 3] = -np.dot(s, eye), -np.dot(u, eye), np.dot(f, eye)
    return m


def tool_viewpoints(num_points: int, center, radius=5.0, focal=2000.0):
    """[(pos, view, up, focal)] of Viewpoints::create(numPoints, center, radius, focal)."""
    center = _f32(*center)
    radius = np.float32(radius)
    out = []
    if num_points == 1:
        return [(center + _f32(radius, 0.0, 0.0), center, _f32(0.0, 1.0, 0.0), _f32(focal, focal))]
    golden = np.float32(np.pi) * (np.float32(3.0) - np.sqrt(np.float32(5.0)))
    for i in range(num_points):
        z = np.float32(1.0) - (np.float32(2.0) * np.float32(i)) / np.float32(num_points - 1)
        r = np.sqrt(np.float32(1.0) - z * z)
        phi = np.float32(i) * golden
        pos = center + radius * _f32(r * np.cos(phi), r * np.sin(phi), z)
        view = center
        world_up = _f32(0.0, 1.0, 0.0)
        right = _normalize(np.cross(world_up, view))
        up = np.cross(view, right)
        out.append((pos, view, up, _f32(focal, focal)))
    return out


def tool_view_matrix(pos, view, up):
    """RasterizerSoftware::render's viewMat: Camera::setLookAt(pos, view, up) then Camera::viewMat()
    (the tool round-trips the basis through a float quaternion; taken here as the basis itself)."""
    e_z = _normalize(pos - view)
    e_x = _normalize(np.cross(up, e_z))
    e_y = _normalize(np.cross(e_z, e_x))
    dist = np.sqrt(np.dot(pos - view, pos - view))
    eye = e_z * dist + view              # mat * (0, 0, dist) + center
    return _lookat_rh(eye, view, e_y)    # lookAt(eye, center, mat * (0, 1, 0))


def tool_bounding_box_center(xyz):
    """Pointcloud::getBoundingBox then (max + min) * 0.5f."""
    p = np.asarray(xyz, np.float32)
    return (p.max(0) + p.min(0)) * np.float32(0.5)
