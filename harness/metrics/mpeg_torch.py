"""The mpeg-gsc-metrics set (:mod:`.mpeg`) in torch: every image compared with one reference at once,
on the study's device.

The arithmetic is :mod:`.mpeg`'s, operation for operation, and where the tool is exact so is this
form: the 8-bit quantisation (float32 product, round half away from zero, clamp), the default
BT.709 conversion (float64 of float32 coefficients, each plane rounded to float32) and the QMIV
integer one, and the integer sums of squared RGB (and QMIV YUV) differences (int64: **bit-equal**).
The default mode's YUV squared differences are summed by the tool in pixel order (a running
double whose rounding, at 1024×768, moves the PSNR by ~1e-11 dB against a parallel sum): the squares
are computed on the device and added in that order on the host (``np.cumsum``), so those PSNRs are
bit-equal too. The SSIM maps (:mod:`.mpeg_ssim_torch`) and IV-SSIM blocks (:mod:`.ivssim_torch`)
are bit-equal per pixel and per block and reduced on the device in parallel: their means agree
to ~1e-14 (tested to 1e-12). The combinations (PSNRs from the MSEs, the cap, the 1:1:1 and 4:1:1
means) are :mod:`.mpeg`'s own functions, run on the host on the numbers read back per batch.

Only the tool's source rounding (``yuv_rounding="float32"``) is provided: a study measures with it.
"""

from __future__ import annotations

import numpy as np
import torch

from harness.metrics import ivssim, mpeg, mpeg_ssim_torch
from harness.metrics.ivssim_torch import iv_ssim_batch
from harness.metrics.mpeg import _combine, _psnr, _psnr_of_mean

_COEF = torch.as_tensor(mpeg._COEF)  # float64 values of the tool's float32 literals


def quantize(images: torch.Tensor) -> torch.Tensor:
    """8-bit RGB ``(N, H, W, 3)`` of float renders as the tool makes them (:func:`.mpeg.quantize`);
    uint8 input is kept as it is."""
    if images.dtype == torch.uint8:
        return images[..., :3]
    p = images[..., :3].to(torch.float32) * 255.0  # float32 product, as `c.x * scale`
    t = torch.trunc(p)
    r = t + torch.where((p - t).abs() >= 0.5, torch.sign(p), torch.zeros((), dtype=p.dtype, device=p.device))
    return torch.nan_to_num(r, nan=0.0).clamp(0, 255).to(torch.uint8)


def yuv_default(rgb: torch.Tensor) -> torch.Tensor:
    """``Image::getYuv`` of uint8 RGB ``(..., 3)``: float64 planes, each rounded to float32."""
    c = rgb.to(torch.float64)
    k = _COEF.tolist()
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    y = k[0][0] * r + k[0][1] * g + k[0][2] * b
    u = k[1][0] * r + k[1][1] * g + k[1][2] * b + 128.0
    v = k[2][0] * r + k[2][1] * g + k[2][2] * b + 128.0
    return torch.stack([p.to(torch.float32).to(torch.float64) for p in (y, u, v)], -1)


def yuv_qmiv(rgb: torch.Tensor) -> torch.Tensor:
    """``Image::getYuvQmiv`` of uint8 RGB ``(..., 3)``: integer BT.709, int64 planes."""
    r, g, b = (rgb[..., i].to(torch.int64) for i in range(3))
    y = ((13933 * r + 46871 * g + 4732 * b + 32768) >> 16).clamp(0, 255)
    u = (((-7509 * r - 25259 * g + (b << 15) + 32768) >> 16) + 128).clamp(0, 255)
    v = ((((r << 15) - 29763 * g - 3005 * b + 32768) >> 16) + 128).clamp(0, 255)
    return torch.stack([y, u, v], -1)


class ToolReferenceT(mpeg.LazySides):
    """A reference render's side of :func:`tool_metrics_batch` for one mode, on ``device``: its
    8-bit RGB and YUV planes in tool row order (bottom-up), their SSIM moments and integer YCbCr
    planes on first use (the torch twin of :class:`.mpeg.ToolReference`)."""

    def __init__(self, ref, *, qmiv: bool = False, device=None):
        ref = torch.as_tensor(ref, device=device)
        self.device = ref.device
        self.qmiv = qmiv
        self.rgb = quantize(ref[None] if ref.dim() == 3 else ref).flip(1)  # (1, H, W, 3), tool buffers are bottom-up
        self.shape = tuple(self.rgb.shape[1:3])
        self.yuv = yuv_qmiv(self.rgb) if qmiv else yuv_default(self.rgb)
        self._ssim = None
        self._qmiv = None

    _to_qmiv = staticmethod(yuv_qmiv)

    def _ssim_side(self) -> mpeg_ssim_torch.PlaneStatsT:
        return mpeg_ssim_torch.plane_stats(self.yuv.permute(0, 3, 1, 2))


def _int_sq_sums(d: torch.Tensor, mask: torch.Tensor | None) -> torch.Tensor:
    """Per image and channel Σ d² ``(N, 3)`` of integer differences over the (masked) pixels: int64,
    exact (equal to the tool's running double sum, whose partial sums are exact integers)."""
    sq = d * d
    if mask is not None:
        sq = sq * mask[..., None].to(sq.dtype)
    return sq.sum((1, 2))


def _sequential_sums(sq: np.ndarray, mask: np.ndarray | None) -> np.ndarray:
    """Σ of float64 squares ``(N, 3, n)`` per image and channel in pixel order, over the pixels of
    ``mask`` ``(N, n)`` when given: the tool's running sum (``np.cumsum`` adds in sequence)."""
    out = np.zeros(sq.shape[:2])
    for k in range(sq.shape[0]):
        for c in range(sq.shape[1]):
            v = sq[k, c] if mask is None else sq[k, c][mask[k]]
            out[k, c] = np.cumsum(v)[-1] if len(v) else 0.0
    return out


def _device_values(prep: ToolReferenceT, tests, masks, ssim: bool, om: bool, iv: bool) -> dict:
    """Every per-image quantity of the batch as device tensors (read back together by the caller)."""
    b = quantize(torch.as_tensor(tests, device=prep.device)).flip(1)
    n, h, w = b.shape[:3]
    if (h, w) != prep.shape:
        raise ValueError(f"image sizes differ: {prep.shape} vs {(h, w)}")
    m = torch.ones((n, h, w), dtype=torch.bool, device=prep.device) if masks is None else \
        (torch.as_tensor(masks, device=prep.device) != 0).reshape(n, h, w).flip(1)
    yb = yuv_qmiv(b) if prep.qmiv else yuv_default(b)
    drgb = prep.rgb.to(torch.int64) - b.to(torch.int64)
    dyuv = prep.yuv - yb
    out = {"rgb": _int_sq_sums(drgb, None), "n_valid": m.sum((1, 2))}
    if om:
        out["rgb_om"] = _int_sq_sums(drgb, m)
    if prep.qmiv:
        out["yuv"] = _int_sq_sums(dyuv, None)
        if om:
            out["yuv_om"] = _int_sq_sums(dyuv, m)
    if ssim:
        planes = yb.permute(0, 3, 1, 2)
        out["ssim"] = mpeg_ssim_torch.ssim_planes(prep.ssim_planes, planes)
        if om:
            out["ssim_om"] = mpeg_ssim_torch.masked_ssim_planes(prep.ssim_planes, planes, m)
    if iv:
        ib = yb if prep.qmiv else yuv_qmiv(b)
        out["rgb_ivssim"] = iv_ssim_batch(prep.rgb, b, ivssim.EQUAL_WEIGHTS)
        out["yuv_ivssim"] = iv_ssim_batch(prep.qmiv_planes, ib, ivssim.DEFAULT_WEIGHTS)
    if not prep.qmiv:  # float squares: summed on the host in pixel order (module docstring)
        sq = (dyuv * dyuv).permute(0, 3, 1, 2).reshape(n, 3, h * w).cpu().numpy()
        flat = m.reshape(n, h * w).cpu().numpy() if om else None
        out["yuv"] = _sequential_sums(sq, None)
        if om:
            out["yuv_om"] = _sequential_sums(sq, flat)
    return out


def _host(values: dict) -> dict:
    """The batch's device tensors on the host in one transfer, as float64 numpy arrays ``(N, k)``
    (exact: every integer sum is below 2^53); host arrays are kept."""
    keys = [k for k, v in values.items() if isinstance(v, torch.Tensor)]
    cols = [values[k].reshape(len(values[k]), -1).to(torch.float64) for k in keys]
    flat = torch.cat(cols, 1).cpu().numpy()
    out = {k: v for k, v in values.items() if k not in keys}
    at = 0
    for k, c in zip(keys, cols):
        out[k] = flat[:, at:at + c.shape[1]]
        at += c.shape[1]
    return out


def tool_metrics_batch(ref: ToolReferenceT, tests, masks=None, *, ssim: bool = True, om: bool = True,
                       iv: bool = True) -> list[dict]:
    """:func:`.mpeg.tool_metrics` of each image of ``tests`` ``(N, H, W, 3)`` (float renders or uint8,
    top-down) against ``ref``, with ``masks`` ``(N, H, W)`` (None: the maskless overload): one dict per
    image with the same keys and values (module docstring for the exactness)."""
    with torch.inference_mode():
        v = _host(_device_values(ref, tests, masks, ssim, om, iv))
    size = ref.shape[0] * ref.shape[1]
    qmiv = ref.qmiv
    rows = []
    for k in range(len(v["rgb"])):
        r: dict = {}
        for space in ("rgb", "yuv"):
            mse = [float(s) / size for s in v[space][k]]
            psnr = [_psnr(x) for x in mse]
            r[f"mse_{space}"], r[f"psnr_{space}"] = mse, psnr
            r[f"{space}_psnr"] = _combine(psnr, True, space) if qmiv else _psnr_of_mean(mse)
            r[f"mse_{space}_om"], r[f"psnr_{space}_om"], r[f"{space}_psnr_om"] = [0.0] * 3, [0.0] * 3, 0.0
        n_valid = int(v["n_valid"][k, 0])
        r["occupancy"] = 0.0
        if om and n_valid > 0:
            for space in ("rgb", "yuv"):
                mse = [float(s) / n_valid for s in v[f"{space}_om"][k]]
                psnr = [_psnr(x) for x in mse]
                r[f"mse_{space}_om"], r[f"psnr_{space}_om"] = mse, psnr
                r[f"{space}_psnr_om"] = _combine(psnr, True, space) if qmiv else _psnr_of_mean(mse)
            r["occupancy"] = 100.0 * n_valid / size
        r["ssim_yuv"], r["yuv_ssim"], r["ssim_yuv_om"], r["yuv_ssim_om"] = [0.0] * 3, 0.0, [0.0] * 3, 0.0
        if ssim:
            full = [float(x) for x in v["ssim"][k]]
            r["ssim_yuv"], r["yuv_ssim"] = full, _combine(full, qmiv, "ssim")
            if om:
                masked = [float(x) for x in v["ssim_om"][k]]
                r["ssim_yuv_om"], r["yuv_ssim_om"] = masked, _combine(masked, qmiv, "ssim")
        r["rgb_ivssim"] = float(v["rgb_ivssim"][k, 0]) if iv else 0.0
        r["yuv_ivssim"] = float(v["yuv_ivssim"][k, 0]) if iv else 0.0
        rows.append(r)
    return rows

