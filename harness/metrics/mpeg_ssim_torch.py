"""mpeg-gsc-metrics' per-plane SSIM and OM-SSIM (:mod:`.mpeg_ssim`) in torch, batched, on any device.

The arithmetic is :mod:`.mpeg_ssim`'s, operation for operation, on whole planes: the tool's padding
(its quirks included: the padded plane is gathered through :func:`.mpeg_ssim.pad_like_tool` applied
to the pixel indices, so both forms pad by the same code), then for each of the 121 taps, in the
tool's order (row offset j outer, column offset i inner), one elementwise float64 multiply and one
add into each accumulator::

    μ  += w[i][j]·P[y+j, x+i]                  σ² += (w[i][j]·(P − μ))·(P − μ)
    OM: wm = w[i][j]·m[y+j, x+i],  μ += wm·P,  Σwm += wm,  then μ /= Σwm (where Σwm ≥ 0.5), σ² as above with wm

Every elementwise operation of IEEE float64 is correctly rounded on every device and torch runs each
as its own kernel (no fused multiply-add in eager mode), so **each pixel's SSIM is bit-equal** to the
numba form's. Only the last step differs: the tool adds the map's values in pixel order (a running
double), here ``sum`` reduces them in parallel; the means of the two agree to ~1e-15 (tested to 1e-12).

Shapes: planes ``(N, C, H, W)`` float64 (N images, C planes each), masks ``(N, H, W)`` (non-zero =
occupied, one per image for all its planes). A reference's side (its padded planes and moments) is
computed once by :func:`plane_stats` and broadcast over the batch.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import torch

from harness.metrics.mpeg_ssim import _W, C1, C2, MASK_THRESHOLD, WINDOW, pad_like_tool

#: the window's taps in the tool's order (j outer, i inner): (j, i, w[i][j])
TAPS = tuple((j, i, float(_W[i, j])) for j in range(WINDOW) for i in range(WINDOW))


@lru_cache(maxsize=8)
def _pad_index(h: int, w: int) -> np.ndarray:
    """Flat pixel index of every padded position: the tool's padding, read off the numpy form."""
    return pad_like_tool(np.arange(h * w, dtype=np.int64).reshape(h, w))


def pad(planes: torch.Tensor) -> torch.Tensor:
    """The tool's padded planes ``(..., H + 10, W + 10)`` of ``planes`` ``(..., H, W)`` (dtype kept)."""
    h, w = planes.shape[-2:]
    idx = torch.as_tensor(_pad_index(h, w), device=planes.device)
    return planes.flatten(-2)[..., idx]


def _window(p: torch.Tensor, j: int, i: int, h: int, w: int) -> torch.Tensor:
    return p[..., j:j + h, i:i + w]


@dataclass(frozen=True)
class PlaneStatsT:
    """A reference's planes ``(1, C, H, W)`` padded as the tool pads them, and their window moments
    (the torch twin of :class:`.mpeg_ssim.PlaneStats`)."""

    padded: torch.Tensor
    mu: torch.Tensor
    var: torch.Tensor


def moments(padded: torch.Tensor, h: int, w: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Window mean μ and ``Σ (w·(P − μ))·(P − μ)`` of padded planes (the numba ``_moments``)."""
    mu = torch.zeros(padded.shape[:-2] + (h, w), dtype=torch.float64, device=padded.device)
    for j, i, wt in TAPS:
        mu.add_(_window(padded, j, i, h, w) * wt)
    s = torch.zeros_like(mu)
    for j, i, wt in TAPS:
        d = _window(padded, j, i, h, w) - mu
        s.add_((d * wt) * d)
    return mu, s


def plane_stats(planes: torch.Tensor) -> PlaneStatsT:
    """:class:`PlaneStatsT` of reference planes ``(1, C, H, W)`` in tool row order."""
    h, w = planes.shape[-2:]
    padded = pad(planes.to(torch.float64))
    mu, var = moments(padded, h, w)
    return PlaneStatsT(padded, mu, var)


def _ratio(mu_a, mu_b, s_aa, s_bb, s_ab) -> torch.Tensor:
    """The tool's per-pixel SSIM expression, its operations in its order."""
    num = ((2 * mu_a) * mu_b + C1) * (2 * s_ab + C2)
    den = ((mu_a * mu_a + mu_b * mu_b) + C1) * ((s_aa + s_bb) + C2)
    return num / den, den


def _mean(values: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """Σ values / count over the valid pixels of each plane ``(N, C)``; 1.0 where none is valid."""
    total = torch.where(valid, values, torch.zeros((), dtype=values.dtype, device=values.device)).sum((-2, -1))
    count = valid.sum((-2, -1))
    return torch.where(count > 0, total / count.clamp(min=1), torch.ones((), dtype=total.dtype, device=total.device))


def ssim_planes(ref: PlaneStatsT, planes: torch.Tensor) -> torch.Tensor:
    """SSIM of each image's planes ``(N, C, H, W)`` against the reference's: float64 ``(N, C)``."""
    h, w = planes.shape[-2:]
    pb = pad(planes.to(torch.float64))
    pa = ref.padded
    mu_b = torch.zeros(pb.shape[:-2] + (h, w), dtype=torch.float64, device=pb.device)
    for j, i, wt in TAPS:
        mu_b.add_(_window(pb, j, i, h, w) * wt)
    s_bb, s_ab = torch.zeros_like(mu_b), torch.zeros_like(mu_b)
    for j, i, wt in TAPS:
        da = _window(pa, j, i, h, w) - ref.mu
        db = _window(pb, j, i, h, w) - mu_b
        s_bb.add_((db * wt) * db)
        s_ab.add_((da * wt) * db)
    value, den = _ratio(ref.mu, mu_b, ref.var, s_bb, s_ab)
    return _mean(value, den > 0)


def masked_ssim_planes(ref: PlaneStatsT, planes: torch.Tensor, masks: torch.Tensor) -> torch.Tensor:
    """OM-SSIM of each image's planes ``(N, C, H, W)`` against the reference's, image n weighted by
    ``masks[n]`` ``(N, H, W)``: float64 ``(N, C)`` (the numba ``_masked_ssim_sum``)."""
    h, w = planes.shape[-2:]
    pb = pad(planes.to(torch.float64))
    pa = ref.padded
    pm = pad((masks != 0).to(torch.float64))[:, None]  # (N, 1, H + 10, W + 10): shared by the planes
    shape = pb.shape[:-2] + (h, w)
    mu_a, mu_b = (torch.zeros(shape, dtype=torch.float64, device=pb.device) for _ in range(2))
    msum = torch.zeros(pm.shape[:-2] + (h, w), dtype=torch.float64, device=pb.device)
    for j, i, wt in TAPS:
        wm = _window(pm, j, i, h, w) * wt
        mu_a.add_(wm * _window(pa, j, i, h, w))
        mu_b.add_(wm * _window(pb, j, i, h, w))
        msum.add_(wm)
    valid = msum >= MASK_THRESHOLD
    divisor = torch.where(valid, msum, torch.ones((), dtype=msum.dtype, device=msum.device))
    mu_a.div_(divisor)
    mu_b.div_(divisor)
    s_aa, s_bb, s_ab = (torch.zeros_like(mu_a) for _ in range(3))
    for j, i, wt in TAPS:
        wm = _window(pm, j, i, h, w) * wt
        da = _window(pa, j, i, h, w) - mu_a
        db = _window(pb, j, i, h, w) - mu_b
        wda = wm * da
        s_aa.add_(wda * da)
        s_bb.add_((wm * db) * db)
        s_ab.add_(wda * db)
    value, den = _ratio(mu_a, mu_b, s_aa / divisor, s_bb / divisor, s_ab / divisor)
    return _mean(value, valid & (den > 0))

