"""The image metrics of MPEG's Gaussian-splat metric tool, mpeg-gsc-metrics v3.0, number for number.

Source (ISO/IEC, BSD), read at github.com/little-little-point-cloud-group/gscem @
c4a0c1cae5693c5ef5697b62ca2e85af12fce36c, ``submodules/mpeg-gsc-metrics/source/``:
``metric.cpp`` (``Metric::compute``), ``util/image.hpp`` (``Image::from``, ``getYuv``,
``getYuvQmiv``), ``main.cpp`` (occupancy maps). Written from reading it; no code copied.

**8-bit renders.** The tool scores ``Image<uint8_t, 3>``: each float colour c (composited on black)
becomes ``clamp(std::round(c * 255.f), 0, 255)`` — product in float32, round half *away from zero*,
then clamp (image.hpp: ``static_cast<T>( std::clamp( std::round( c.x * scale ), 0.f, 255.f ) )``).
:func:`quantize` does exactly that. Peak = 255.

**Per channel** (sums in pixel order of the tool's bottom-up buffer, double)::

    MSE_c = Σ (A_c − B_c)² / (W·H)        PSNR_c = min(999.99, 10·log10(255² / MSE_c))   (MSE 0 → 999.99)

**Colour spaces.** Default (``getYuv``): full-range BT.709 with float32 literals, double arithmetic,
+128 on chroma, no clamp, the triple returned through ``glm::vec3`` (rounded to float32)::

    Y = 0.2126f R + 0.7152f G + 0.0722f B
    U = −0.1146f R − 0.3854f G + 0.5f B + 128      V = 0.5f R − 0.4542f G − 0.0458f B + 128

QMIV (``--computeQmiv=1``, ``getYuvQmiv``): 16-bit fixed point, floor shift, clamp to 0..255::

    Y = (13933 R + 46871 G + 4732 B + 32768) >> 16
    U = ((−7509 R − 25259 G + (B << 15) + 32768) >> 16) + 128
    V = (((R << 15) − 29763 G − 3005 B + 32768) >> 16) + 128

**Combined values** (metric.cpp, "QMIV = 4:1:1 MPEG = 1:1:1")::

    default  RGB-PSNR = min(999.99, 10·log10(255² / ((MSE_R + MSE_G + MSE_B)/3)))   (mean 0 → 999.99)
             YUV-PSNR = the same of (MSE_Y + MSE_U + MSE_V)/3      YUV-SSIM = (S_Y + S_U + S_V)/3
    QMIV     RGB-PSNR = (PSNR_R + PSNR_G + PSNR_B)/3                YUV-PSNR = (4 PSNR_Y + PSNR_U + PSNR_V)/6
             YUV-SSIM = (4 S_Y + S_U + S_V)/6

SSIM / OM-SSIM per Y, U, V plane: :mod:`harness.metrics.mpeg_ssim` (its padding quirks included).
IV-SSIM (RGB and YCbCr, PMBB ``xIVSSIM``, the same in both modes): :mod:`harness.metrics.ivssim`.

**Occupancy-masked (OM) metrics.** The same sums over the pixels where the mask is non-zero,
divided by their count; ``occupancy = 100·count/(W·H)`` %. With an empty mask every OM-PSNR field
stays 0.0 and occupancy 0 (and those zeros enter the tool's averages); OM-SSIM is then 1.0.
Mask rule: see :func:`occupancy_mask`.

**Averaging views** (``Metric::getAverage``): plain mean of every per-view value, PSNRs in dB.

**Compiler note.** A GCC ``-O3`` build of the tool vectorises the MSE loop and drops the float32
rounding of Y and U there (V and the SSIM path keep it); ``yuv_rounding="gcc-o3"`` reproduces such a
build, the default ``"float32"`` follows the source (and clang). They differ by < 1e-6 dB.
"""

from __future__ import annotations

import math

import numpy as np

from harness.metrics import ivssim, mpeg_pixels, mpeg_ssim

PEAK = 255.0
CAP = 999.99
#: the tool's fragment-opacity threshold for occupancy (``alpha >= ( 10.0f / 255.0f )``)
OCCUPANCY_ALPHA = np.float32(10.0) / np.float32(255.0)
_F = np.float32
_COEF = np.array([[_F(0.2126), _F(0.7152), _F(0.0722)],
                  [-_F(0.1146), -_F(0.3854), _F(0.5)],
                  [_F(0.5), -_F(0.4542), -_F(0.0458)]], np.float64)
YUV_ROUNDING = {"float32": (True, True, True), "gcc-o3": (False, False, True)}


def quantize(image) -> np.ndarray:
    """8-bit RGB ``(H, W, 3)`` as the tool makes it from a float render; uint8 input is kept as is.
    ``std::round`` is half away from zero: floor(p + 0.5) would send 0.49999997 to 1
    (:func:`.mpeg_pixels.quantize_f32`)."""
    a = np.asarray(image)
    if a.dtype == np.uint8:
        return np.ascontiguousarray(a[..., :3])
    return mpeg_pixels.quantize_f32(np.asarray(a[..., :3], np.float32))  # float32 product, as `c.x * scale`


def yuv_default(rgb: np.ndarray, rounding=(True, True, True)) -> np.ndarray:
    """Image::getYuv of uint8 RGB: float64 planes (H, W, 3), each rounded to float32 where asked
    (exact in double before that: < 40 significant bits)."""
    return mpeg_pixels.yuv_default(rgb, _COEF, tuple(bool(r) for r in rounding))


def yuv_qmiv(rgb: np.ndarray) -> np.ndarray:
    """Image::getYuvQmiv of uint8 RGB: integer BT.709 (int64 planes, H, W, 3)."""
    return mpeg_pixels.yuv_qmiv(rgb)


def occupancy_mask(alpha_ref, alpha_test=None) -> np.ndarray:
    """The OM mask: pixels occupied in *either* render (the tool's rule), bool (H, W).

    The issue asks for a mask "taken from the reference render's alpha"; the tool takes the union
    of both renders' occupancy maps (main.cpp: ``imageOcmUnion ... ( val0 || val1 ) ? 1 : 0``), and
    we follow the tool: pass the test render's alpha too. Occupied = ``alpha >= 10/255`` (the
    software rasterizer's ``if ( alpha >= ( 10.0f / 255.0f ) ) ocm[0].get( u, v ) = 255;``).
    Our renderers report the *accumulated* alpha 1 − T of each pixel, whereas the tool marks a
    pixel when one fragment's alpha passes the threshold (the GPU path with a strict ``>``); a pixel
    lit only by several faint splats counts here and not there (at silhouettes).
    """
    m = np.asarray(alpha_ref, np.float32) >= OCCUPANCY_ALPHA
    if alpha_test is not None:
        m |= np.asarray(alpha_test, np.float32) >= OCCUPANCY_ALPHA
    return m


def _psnr(mse: float) -> float:
    return CAP if mse == 0.0 else min(CAP, 10.0 * math.log10(PEAK * PEAK / mse))


def _psnr_of_mean(mses) -> float:
    m = (mses[0] + mses[1] + mses[2]) / 3.0
    return min(CAP, 10.0 * math.log10(PEAK * PEAK / m)) if m > 0 else CAP


def _combine(values, qmiv: bool, kind: str) -> float:
    a, b, c = values
    if kind == "ssim":
        return (4.0 * a + b + c) / 6.0 if qmiv else (a + b + c) / 3.0
    if kind == "rgb":
        return (a + b + c) / 3.0
    return (4.0 * a + b + c) / 6.0


class LazySides:
    """What a reference side computes on first use, whatever holds its planes (numpy here, torch in
    :mod:`.mpeg_torch`): the integer YCbCr planes IV-SSIM reads in every mode, and the YUV planes'
    SSIM side. ``_to_qmiv`` and ``_ssim_side`` are the holder's own forms."""

    @property
    def qmiv_planes(self):
        """The reference's integer (QMIV) YCbCr planes (computed once; the YUV planes in QMIV mode)."""
        if self.qmiv:
            return self.yuv
        if self._qmiv is None:
            self._qmiv = self._to_qmiv(self.rgb)
        return self._qmiv

    @property
    def ssim_planes(self):
        if self._ssim is None:
            self._ssim = self._ssim_side()
        return self._ssim


class ToolReference(LazySides):
    """The reference render's side of :func:`tool_metrics` for one mode, prepared once and reused
    for every image compared with it: 8-bit RGB and YUV planes in tool row order, and each YUV
    plane's padded SSIM moments (:func:`harness.metrics.mpeg_ssim.plane_stats`, on first use)."""

    def __init__(self, ref, *, qmiv: bool = False, rows_top_down: bool = True, yuv_rounding: str = "float32"):
        a = quantize(ref)
        self.shape = a.shape[:2]
        self.qmiv, self.rows_top_down, self.yuv_rounding = qmiv, rows_top_down, yuv_rounding
        self.rgb = a[::-1] if rows_top_down else a  # tool buffers are bottom-up (OpenGL)
        rnd = YUV_ROUNDING[yuv_rounding]
        self.yuv = yuv_qmiv(self.rgb) if qmiv else yuv_default(self.rgb)
        self.yuv_diff = self.yuv if qmiv or rnd == (True,) * 3 else yuv_default(self.rgb, rnd)  # MSE operand
        self._ssim = None
        self._qmiv = None

    def yuv_of(self, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(planes for SSIM, planes for the MSE) of another 8-bit image in tool row order, as the reference's."""
        if self.qmiv:
            yb = yuv_qmiv(b)
            return yb, yb
        rnd = YUV_ROUNDING[self.yuv_rounding]
        yb = yuv_default(b)
        return yb, yb if rnd == (True,) * 3 else yuv_default(b, rnd)

    _to_qmiv = staticmethod(yuv_qmiv)

    def _ssim_side(self) -> list:
        return [mpeg_ssim.plane_stats(self.yuv[..., c]) for c in range(3)]


def tool_metrics(ref, test, mask=None, *, qmiv: bool = False, ssim: bool = True, om: bool = True,
                 iv: bool = True, rows_top_down: bool = True, yuv_rounding: str = "float32") -> dict:
    """Every per-view value the tool prints, for two renders (float or uint8, ``(H, W, 3)``).

    ``ref`` may be a :class:`ToolReference` (its mode wins over ``qmiv``, ``rows_top_down`` and
    ``yuv_rounding``). ``mask``: None → the tool's maskless overload (all ones: OM = full frame,
    occupancy 100 %); else a boolean/0-1 array, non-zero = occupied (:func:`occupancy_mask`). Keys:
    ``mse_rgb, psnr_rgb, mse_yuv, psnr_yuv`` (3-lists), ``rgb_psnr, yuv_psnr`` (combined), the same
    with ``_om``, ``occupancy`` (%), ``ssim_yuv, ssim_yuv_om`` (3-lists), ``yuv_ssim, yuv_ssim_om``,
    ``rgb_ivssim, yuv_ivssim`` (``iv=False``, the tool's ``--computeIvssim=0``: left at 0.0).
    """
    prep = ref if isinstance(ref, ToolReference) else \
        ToolReference(ref, qmiv=qmiv, rows_top_down=rows_top_down, yuv_rounding=yuv_rounding)
    qmiv = prep.qmiv
    b = quantize(test)
    if prep.shape != b.shape[:2]:
        raise ValueError(f"image sizes differ: {prep.shape} vs {b.shape[:2]}")
    h, w = prep.shape
    m = np.ones((h, w), bool) if mask is None else (np.asarray(mask) != 0)
    if m.shape != (h, w):
        raise ValueError(f"mask is {m.shape}, images are {(h, w)}")
    if prep.rows_top_down:  # tool buffers are bottom-up (OpenGL); order matters for sums and SSIM padding
        b, m = b[::-1], m[::-1]
    a = prep.rgb
    size = h * w
    yb, yb_diff = prep.yuv_of(b)
    yuv_sums = mpeg_pixels.square_sums_int if qmiv else mpeg_pixels.square_sums_float
    sums = {"rgb": mpeg_pixels.square_sums_int(a, b, m), "yuv": yuv_sums(prep.yuv_diff, yb_diff, m)}
    r: dict = {}
    for space, (full, _) in sums.items():
        mse = [float(s) / size for s in full]
        psnr = [_psnr(x) for x in mse]
        r[f"mse_{space}"], r[f"psnr_{space}"] = mse, psnr
        if not qmiv:
            r[f"{space}_psnr"] = _psnr_of_mean(mse)
        else:
            r[f"{space}_psnr"] = _combine(psnr, True, space)
        r[f"mse_{space}_om"], r[f"psnr_{space}_om"], r[f"{space}_psnr_om"] = [0.0] * 3, [0.0] * 3, 0.0
    n_valid = int(np.count_nonzero(m))
    r["occupancy"] = 0.0
    if om and n_valid > 0:
        for space, (_, part) in sums.items():
            mse = [float(s) / n_valid for s in part]
            psnr = [_psnr(x) for x in mse]
            r[f"mse_{space}_om"], r[f"psnr_{space}_om"] = mse, psnr
            r[f"{space}_psnr_om"] = _combine(psnr, True, space) if qmiv else _psnr_of_mean(mse)
        r["occupancy"] = 100.0 * n_valid / size
    r["ssim_yuv"], r["yuv_ssim"], r["ssim_yuv_om"], r["yuv_ssim_om"] = [0.0] * 3, 0.0, [0.0] * 3, 0.0
    if ssim:  # OM-SSIM is computed even for an empty mask (then 1.0 per plane), as the tool does
        full, masked = mpeg_ssim.ssim_yuv(prep.ssim_planes, yb, m if om else None)
        r["ssim_yuv"], r["yuv_ssim"] = full, _combine(full, qmiv, "ssim")
        if om:
            r["ssim_yuv_om"], r["yuv_ssim_om"] = masked, _combine(masked, qmiv, "ssim")
    r["rgb_ivssim"] = r["yuv_ivssim"] = 0.0
    if iv:  # PMBB's integer YCbCr whatever the mode: the QMIV planes when they are at hand
        ia, ib = prep.qmiv_planes, (yb if qmiv else yuv_qmiv(b))
        r["rgb_ivssim"] = ivssim.iv_ssim_planes(a, b, ivssim.EQUAL_WEIGHTS)
        r["yuv_ivssim"] = ivssim.iv_ssim_planes(ia, ib, ivssim.DEFAULT_WEIGHTS)
    return r


def average_views(results: list[dict]) -> dict:
    """``Metric::getAverage``: the plain mean of every field over all views (and frames), in order."""
    out: dict = {}
    for key, first in results[0].items():
        if isinstance(first, list):
            acc = [0.0] * len(first)
            for res in results:
                acc = [x + y for x, y in zip(acc, res[key])]
            out[key] = [x / len(results) for x in acc]
        else:
            acc = 0.0
            for res in results:
                acc += res[key]
            out[key] = acc / len(results)
    return out
