"""IV-SSIM of mpeg-gsc-metrics (:mod:`.ivssim`, PMBB ``xIVSSIM``) in torch, batched, on any device.

The same steps as the numba form, each on whole pictures of a batch ``(N, 3, H, W)``:

* the global colour shift ``g_c = clip(round(Σ (B_c − A_c) / (W·H)), −3, 3)``: int64 sums (exact),
  wrapped to int32 as the tool's accumulator, rounded half away from zero in integers;
* the corresponding-pixel search over the 25 displacements in the tool's order (dy outer, dx inner),
  int32 errors ``Σ_c w_c (T_c + s_c − R_c(p + d))²``, a strictly smaller error replacing the best
  (the first minimum wins), then the shifted picture gathered from the edge-replicated reference;
* the 8×8 block sums at stride 4 read off int64 summed-area tables (exact), and per block the
  tool's ``(2μxμy + C1)/(μx² + μy² + C1) · (2σxy + C2)/(σx² + σy² + C2)`` in float64, operation for
  operation, so **each block's value is bit-equal** to the numba form's.

Only the sum of the block values differs: the tool adds them per block row and then over rows with
Kahan–Babuška–Neumaier compensation, here ``sum`` reduces them in parallel (float64); both are within
an ulp or two of the exact sum, and the results agree to ~1e-16 (tested to 1e-12).
"""

from __future__ import annotations

import torch

from harness.metrics.ivssim import BLOCK, C1, C2, MARGIN, MAX_SHIFT, SEARCH, STRIDE, block_count


def global_colour_shift(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``g`` ``(N, 3)`` int32 of pictures ``a``, ``b`` ``(N, 3, H, W)`` (:func:`.ivssim.global_colour_shift`)."""
    q = a.shape[-2] * a.shape[-1]
    s = (b.to(torch.int64) - a.to(torch.int64)).sum((-2, -1))
    s = torch.remainder(s + (1 << 31), 1 << 32) - (1 << 31)  # the tool's int32 accumulator
    r = torch.div(2 * s.abs() + q, 2 * q, rounding_mode="floor")
    return (r.clamp(max=MAX_SHIFT) * torch.where(s >= 0, 1, -1)).to(torch.int32)


def _edge_pad(x: torch.Tensor, m: int) -> torch.Tensor:
    """``x`` ``(..., H, W)`` padded by ``m`` on each side, edges replicated (any dtype)."""
    h, w = x.shape[-2:]
    rows = torch.arange(-m, h + m, device=x.device).clamp(0, h - 1)
    cols = torch.arange(-m, w + m, device=x.device).clamp(0, w - 1)
    return x[..., rows[:, None], cols[None, :]]


def shift_compensate(ref: torch.Tensor, tst: torch.Tensor, shift: torch.Tensor, weights) -> torch.Tensor:
    """``xShftCompPic::xGenShftCompPic``: ``ref`` ``(N, 3, H, W)`` moved, pixel by pixel, onto ``tst``
    (best of the 25 displacements), minus ``shift`` ``(N, 3)``, clipped to 0..255; int32 ``(N, 3, H, W)``."""
    n, _, h, w = tst.shape
    padded = _edge_pad(ref.to(torch.int32), MARGIN)
    t = tst.to(torch.int32) + shift[:, :, None, None]
    wt = torch.as_tensor(weights, dtype=torch.int32, device=tst.device)[None, :, None, None]
    best = torch.full((n, h, w), torch.iinfo(torch.int32).max, dtype=torch.int32, device=tst.device)
    best_k = torch.zeros((n, h, w), dtype=torch.int64, device=tst.device)
    k = 0
    for dy in range(-SEARCH, SEARCH + 1):
        for dx in range(-SEARCH, SEARCH + 1):
            r = padded[..., MARGIN + dy:MARGIN + dy + h, MARGIN + dx:MARGIN + dx + w]
            d = t - r
            err = ((d * d) * wt).sum(1, dtype=torch.int32)  # exact: < 2^31
            better = err < best
            best = torch.where(better, err, best)
            best_k = torch.where(better, k, best_k)
            k += 1
    side = 2 * SEARCH + 1
    yy = torch.arange(h, device=tst.device)[:, None] + MARGIN + torch.div(best_k, side, rounding_mode="floor") - SEARCH
    xx = torch.arange(w, device=tst.device)[None, :] + MARGIN + best_k % side - SEARCH
    flat = (yy * padded.shape[-1] + xx)[:, None].expand(n, 3, h, w).reshape(n, 3, -1)
    moved = torch.gather(padded.reshape(n, 3, -1), 2, flat).reshape(n, 3, h, w)
    return (moved - shift[:, :, None, None]).clamp(0, 255)


def _block_sums(x: torch.Tensor, rows: int, cols: int) -> torch.Tensor:
    """Σ over each 8×8 block at stride 4 of int64 ``x`` ``(..., H, W)`` (summed-area table: exact)."""
    sat = torch.nn.functional.pad(x.cumsum(-1).cumsum(-2), (1, 0, 1, 0))
    y0 = torch.arange(rows, device=x.device) * STRIDE
    x0 = torch.arange(cols, device=x.device) * STRIDE
    y1, x1 = y0 + BLOCK, x0 + BLOCK
    at = lambda ys, xs: sat[..., ys[:, None], xs[None, :]]  # noqa: E731
    return at(y1, x1) - at(y0, x1) - at(y1, x0) + at(y0, x0)


def block_ssim_sums(tst: torch.Tensor, ref: torch.Tensor) -> torch.Tensor:
    """Σ over the blocks of ``CalcBlckAvg`` with the luminance term, per plane of ``(N, C, H, W)``
    integer pictures: float64 ``(N, C)`` (the numba ``_block_ssim_sum``, summed in parallel)."""
    h, w = tst.shape[-2:]
    rows, cols = (h - BLOCK) // STRIDE + 1, (w - BLOCK) // STRIDE + 1
    r, t = ref.to(torch.int64), tst.to(torch.int64)
    sr, st, srr, stt, srt = (_block_sums(v, rows, cols).to(torch.float64) for v in (r, t, r * r, t * t, r * t))
    inv = 1.0 / 64.0
    avg_r, avg_t = sr * inv, st * inv
    var_r = srr * inv - avg_r * avg_r
    var_t = stt * inv - avg_t * avg_t
    cov = srt * inv - avg_r * avg_t
    lum = ((2 * avg_r) * avg_t + C1) / ((avg_r * avg_r + avg_t * avg_t) + C1)
    cs = (2 * cov + C2) / ((var_r + var_t) + C2)
    return (lum * cs).sum((-2, -1))


def iv_ssim_batch(a: torch.Tensor, b: torch.Tensor, weights) -> torch.Tensor:
    """``xIVSSIM::calcPicIVSSIM(Tst = a, Ref = b[n])`` for each image n: ``a`` ``(1 or N, H, W, 3)`` and
    ``b`` ``(N, H, W, 3)`` integer pictures in 0..255, tool row order -> float64 ``(N,)``, NaN below 8 px
    (:func:`.ivssim.iv_ssim_planes`; the weighted combination is its operations in its order)."""
    n, h, w, _ = b.shape
    if h < BLOCK or w < BLOCK:
        return torch.full((n,), float("nan"), dtype=torch.float64, device=b.device)
    pa = a.permute(0, 3, 1, 2).to(torch.int32).expand(n, 3, h, w)
    pb = b.permute(0, 3, 1, 2).to(torch.int32)
    g = global_colour_shift(pa, pb)
    blocks = block_count(h) * block_count(w)
    t2r = block_ssim_sums(pa, shift_compensate(pb, pa, g, weights)) / blocks
    r2t = block_ssim_sums(pb, shift_compensate(pa, pb, -g, weights)) / blocks
    inv = 1.0 / float(sum(weights))
    w0, w1, w2 = (int(x) for x in weights)
    combine = lambda s: ((s[:, 0] * w0 + s[:, 1] * w1) + s[:, 2] * w2) * inv  # noqa: E731
    return torch.minimum(combine(t2r), combine(r2t))
