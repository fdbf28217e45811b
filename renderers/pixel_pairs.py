"""Sparse (pixel, splat) compositing for frozen geometry: the camera-aware pruners' workhorse.

LightGSPrune and ConfSplatPrune render the *same* projected splats many times, changing only the
opacities. The tile rasterizer (:mod:`renderers.reference`) evaluates every splat of a 16×16 tile at all
256 pixels; at the low resolutions these pruners use, almost all of that work lands outside the splats'
footprints (bonsai-7k-mini at 128 px: ~500k tile entries × 256 pixels for ~2M real pairs). Here each
view's footprints are enumerated once (numba, CPU):

1. :func:`build_pairs`: for every visible splat j of a :class:`renderers.projection.Projected`, in
   front-to-back depth order (stable, ties by scene order, as the reference), and every pixel centre
   p = (i, k) with |i − x| ≤ r and |k − y| ≤ r (the reference's default ``footprint="box"``), with
   d = p − means2d and power = −½(a dx² + c dy²) − b dx dy in float32 as the reference computes it:
   keep the pair when power ≤ 0 and min(0.99, o_max·e^power) ≥ 1/255, o_max being the projection's
   opacity. Any opacity later passed to :func:`composite` must be ≤ o_max (gating only lowers it), so
   a dropped pair could never pass the α test. Only pixels inside the ellipse's bounding box for that
   test are visited (:func:`candidate_extent`). Pairs are stored grouped by pixel (CSR offsets), front
   to back inside a pixel.
2. :func:`composite`: per pixel, front to back: α = min(0.99, o·g), skipped when α < 1/255;
   ``C += c·α·T; T ← T(1 − α)``; finally ``C += T·bg``. ``early_stop=True`` is graphdeco's termination
   (the splat whose T(1 − α) would drop below 1e-4 is not composited and ends the pixel), as the
   reference's ``early_stop=True``. Statistics per visible splat, over the pairs that were composited:
   Σ o·T (LightGaussian's significance), Σ α·T and the count.
3. :func:`composite_grad` / :func:`render_pairs`: the exact gradient of the image w.r.t. the opacities.
   With S_k = Σ_{m>k} c_m α_m T_m + T_final·bg (everything behind pair k),
   ∂C/∂α_k = c_k T_k − S_k / (1 − α_k), and ∂α_k/∂o = g_k unless the 0.99 clamp is active; skipped
   pairs get no gradient (the α tests and the early-stop decision are not differentiated). Optionally
   also w.r.t. the per-splat colours: ∂C/∂c_j = Σ_pairs α_k T_k (ConfSplat's SH saliency needs it).

The image equals ``renderers.reference.rasterize(..., footprint="box")`` up to float rounding, except
that the reference retires a tile once all its pixels have T < 1e-7 (effects below 1e-7); the tests
check images, statistics and gradients against it. Everything runs serially, so results are
deterministic.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass

import numba as nb
import numpy as np
import torch

from renderers.projection import Projected
from renderers.reference import ALPHA_MAX, ALPHA_MIN, T_EARLY_STOP

_F32_ALPHA_MAX = np.float32(ALPHA_MAX)
_F32_ALPHA_MIN = np.float32(ALPHA_MIN)


@contextmanager
def torch_threads(n: int):
    """Run the block with ``n`` torch intra-op threads (``n`` ≤ 0: unchanged), restoring them after.

    The pruners' torch work is many small operations (≤ a few M elements); on the shared 2-core
    machine under load, 2 threads made a ConfSplat step 14× slower than 1 (0.28 vs 0.02 s on a
    150-splat scene at load 15), so the pruners default to one thread."""
    before = torch.get_num_threads()
    if n > 0:
        torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)


@dataclass
class PixelPairs:
    """One view's pairs. ``start`` (H·W + 1,) CSR offsets per pixel (row-major) into ``splat`` (P,)
    (index into the view's visible splats) and ``gauss`` (P,) e^power. ``ids`` (M,) scene index of each
    visible splat, ``colors`` (M, 3), ``opacities`` (M,) the o_max used to filter."""

    start: np.ndarray
    splat: np.ndarray
    gauss: np.ndarray
    ids: np.ndarray
    colors: np.ndarray
    opacities: np.ndarray
    width: int
    height: int

    def __len__(self) -> int:
        return int(self.splat.shape[0])

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.start, self.splat, self.gauss, self.ids, self.colors, self.opacities))


@dataclass
class PairOutput:
    image: np.ndarray  # (H, W, 3) float32
    opacity_t: np.ndarray | None = None  # (M,) float64 Σ_p o·T
    alpha_t: np.ndarray | None = None  # (M,) float64 Σ_p α·T
    hits: np.ndarray | None = None  # (M,) int64
    saved: _Saved | None = None  # transmittances for composite_grad (save=True)


def candidate_extent(conics: np.ndarray, opacities: np.ndarray, radii: np.ndarray):
    """Half-widths (x, y) of the region where a splat can pass the α test, capped by its radius.

    α ≥ 1/255 needs o·exp(−½ dᵀQd) ≥ 1/255, i.e. dᵀQd ≤ k² with k² = 2·ln(255·o) (no pixel when
    o < 1/255). That ellipse spans ±k·√Σ_xx in x and ±k·√Σ_yy in y, Σ = Q⁻¹: for Q = [[a, b], [b, c]],
    Σ_xx = c/(ac − b²), Σ_yy = a/(ac − b²). A 1e-3 px margin absorbs rounding; −1 marks "no pixel"."""
    a, b, c = (conics[:, i].astype(np.float64) for i in range(3))
    det = np.maximum(a * c - b * b, 1e-30)
    k2 = np.maximum(2.0 * np.log(255.0 * np.maximum(opacities.astype(np.float64), 1e-30)), 0.0)
    r = radii.astype(np.float64)
    hx = np.minimum(np.sqrt(k2 * c / det) + 1e-3, r + 1e-3)
    hy = np.minimum(np.sqrt(k2 * a / det) + 1e-3, r + 1e-3)
    empty = k2 <= 0
    hx[empty] = -1.0
    hy[empty] = -1.0
    return hx, hy


@nb.njit(cache=True, inline="always")
def _gauss(dx, dy, ca, cb, cc, r, o):
    """e^power of a candidate pair (float32, the reference's arithmetic), or −1 when it fails a test."""
    if abs(dx) > r or abs(dy) > r:
        return np.float32(-1.0)
    power = np.float32(-0.5) * (ca * dx * dx + cc * dy * dy) - cb * dx * dy
    if power > np.float32(0.0):
        return np.float32(-1.0)
    g = np.exp(power)
    if min(_F32_ALPHA_MAX, o * g) < _F32_ALPHA_MIN:
        return np.float32(-1.0)
    return g


@nb.njit(cache=True)
def _build(mx, my, ca, cb, cc, rad, omax, x0, x1, y0, y1, w, h, fill, counts, out_splat, out_g):
    """Pass ``fill=False``: count pairs per pixel into ``counts``; ``fill=True``: write them at the
    cursors in ``counts`` (CSR starts on entry). Splats are visited in the given (depth) order."""
    for j in range(mx.shape[0]):
        for yy in range(y0[j], y1[j] + 1):
            dy = np.float32(yy) - my[j]
            for xx in range(x0[j], x1[j] + 1):
                dx = np.float32(xx) - mx[j]
                g = _gauss(dx, dy, ca[j], cb[j], cc[j], rad[j], omax[j])
                if g < np.float32(0.0):
                    continue
                p = yy * w + xx
                if fill:
                    k = counts[p]
                    out_splat[k] = j
                    out_g[k] = g
                counts[p] += 1


def build_pairs(proj: Projected) -> PixelPairs:
    """Enumerate the (pixel, splat) pairs of ``proj`` (see the module docstring)."""
    w, h = int(proj.width), int(proj.height)
    cpu = lambda t: t.detach().to("cpu", torch.float32).numpy()
    order = torch.sort(proj.depths.detach(), stable=True).indices.cpu().numpy()
    m2d, con, rad, omax = (
        cpu(proj.means2d)[order],
        cpu(proj.conics)[order],
        cpu(proj.radii)[order],
        cpu(proj.opacities)[order],
    )
    hx, hy = candidate_extent(con, omax, rad)
    x0 = np.maximum(np.ceil(m2d[:, 0] - hx), 0).astype(np.int64)
    x1 = np.minimum(np.floor(m2d[:, 0] + hx), w - 1).astype(np.int64)
    y0 = np.maximum(np.ceil(m2d[:, 1] - hy), 0).astype(np.int64)
    y1 = np.minimum(np.floor(m2d[:, 1] + hy), h - 1).astype(np.int64)
    cols = [np.ascontiguousarray(a) for a in (m2d[:, 0], m2d[:, 1], con[:, 0], con[:, 1], con[:, 2])]
    counts = np.zeros(w * h, np.int64)
    dummy_s, dummy_g = np.zeros(0, np.int32), np.zeros(0, np.float32)
    _build(*cols, rad, omax, x0, x1, y0, y1, w, h, False, counts, dummy_s, dummy_g)
    start = np.zeros(w * h + 1, np.int64)
    np.cumsum(counts, out=start[1:])
    cursor = start[:-1].copy()
    splat_sorted = np.empty(int(start[-1]), np.int32)
    gauss = np.empty(int(start[-1]), np.float32)
    _build(*cols, rad, omax, x0, x1, y0, y1, w, h, True, cursor, splat_sorted, gauss)
    # stored splat index: position in the Projected arrays (undo the depth order)
    splat = order.astype(np.int32)[splat_sorted]
    return PixelPairs(start, splat, gauss, proj.ids.detach().cpu().numpy().astype(np.int64),
                      cpu(proj.colors), cpu(proj.opacities), w, h)


@nb.njit(cache=True)
def _forward(start, splat, gauss, op, colors, bg, early_stop, stats, image, t_final, opt, alt, hits, t_pair):
    """Front-to-back compositing per pixel. With ``t_pair`` of length P, T before each pair is recorded
    there (−1: pair not composited) for :func:`_backward`."""
    amax, amin = _F32_ALPHA_MAX, _F32_ALPHA_MIN
    record = t_pair.shape[0] > 0
    for p in range(start.shape[0] - 1):
        t = 1.0
        c0 = c1 = c2 = 0.0
        stopped = False
        for k in range(start[p], start[p + 1]):
            if record:
                t_pair[k] = -1.0
            if stopped:
                continue
            j = splat[k]
            a = min(amax, op[j] * gauss[k])
            if a < amin:
                continue
            t_next = t * (1.0 - a)
            if early_stop and t_next < T_EARLY_STOP:
                stopped = True
                continue
            if record:
                t_pair[k] = t
            wgt = a * t
            c0 += colors[j, 0] * wgt
            c1 += colors[j, 1] * wgt
            c2 += colors[j, 2] * wgt
            if stats:
                opt[j] += op[j] * t
                alt[j] += wgt
                hits[j] += 1
            t = t_next
        image[p, 0] = c0 + t * bg[0]
        image[p, 1] = c1 + t * bg[1]
        image[p, 2] = c2 + t * bg[2]
        t_final[p] = t


@nb.njit(cache=True)
def _backward(start, splat, gauss, op, colors, bg, t_final, t_pair, grad_img, grad_op, grad_col):
    """Back to front per pixel over the pairs :func:`_forward` composited (``t_pair`` ≥ 0);
    ``grad_col`` (M, 3) receives dL/dcolour unless it has no rows."""
    amax = _F32_ALPHA_MAX
    want_col = grad_col.shape[0] > 0
    for p in range(start.shape[0] - 1):
        g0, g1, g2 = grad_img[p, 0], grad_img[p, 1], grad_img[p, 2]
        behind = (g0 * bg[0] + g1 * bg[1] + g2 * bg[2]) * t_final[p]  # dL/dC · S, S = stuff behind
        for k in range(start[p + 1] - 1, start[p] - 1, -1):
            tk = t_pair[k]
            if tk < 0.0:
                continue
            j = splat[k]
            raw = op[j] * gauss[k]
            a = min(amax, raw)
            dc = (g0 * colors[j, 0] + g1 * colors[j, 1] + g2 * colors[j, 2]) * tk
            if want_col:
                wgt = a * tk
                grad_col[j, 0] += g0 * wgt
                grad_col[j, 1] += g1 * wgt
                grad_col[j, 2] += g2 * wgt
            d_alpha = dc - behind / (1.0 - a)
            if raw < amax:
                grad_op[j] += d_alpha * gauss[k]
            behind += dc * a


@dataclass
class _Saved:
    """What :func:`composite_grad` needs from the forward pass: T per pair and per pixel."""

    t_pair: np.ndarray
    t_final: np.ndarray


def _colours(pairs: PixelPairs, colors) -> np.ndarray:
    if colors is None:
        return pairs.colors
    colors = np.ascontiguousarray(colors, dtype=np.float32)
    if colors.shape != pairs.colors.shape:
        raise ValueError(f"colors must be {pairs.colors.shape}, got {colors.shape}")
    return colors


def composite(pairs: PixelPairs, opacities: np.ndarray | None = None, background=(0, 0, 0), *,
              early_stop: bool = False, stats: bool = False, save: bool = False, colors=None) -> PairOutput:
    """Render the pairs with per-visible-splat ``opacities`` (M,) (default ``pairs.opacities``; must not
    exceed them) and ``colors`` (M, 3) (default ``pairs.colors``). Returns the image and, with ``stats``,
    the per-visible-splat statistics; ``save`` keeps the transmittances :func:`composite_grad` needs
    (in ``out.saved``)."""
    op = pairs.opacities if opacities is None else np.ascontiguousarray(opacities, dtype=np.float32)
    cols = _colours(pairs, colors)
    npix = pairs.width * pairs.height
    m = len(pairs.ids) if stats else 0
    image = np.zeros((npix, 3), np.float64)
    saved = _Saved(np.empty(len(pairs) if save else 0, np.float64), np.zeros(npix, np.float64))
    opt, alt, hits = np.zeros(m), np.zeros(m), np.zeros(m, np.int64)
    _forward(pairs.start, pairs.splat, pairs.gauss, op, cols, np.asarray(background, np.float64),
             early_stop, stats, image, saved.t_final, opt, alt, hits, saved.t_pair)
    out = PairOutput(image.astype(np.float32).reshape(pairs.height, pairs.width, 3))
    if stats:
        out.opacity_t, out.alpha_t, out.hits = opt, alt, hits
    if save:
        out.saved = saved
    return out


def composite_grad(pairs: PixelPairs, opacities: np.ndarray, grad_image: np.ndarray, background=(0, 0, 0), *,
                   early_stop: bool = False, saved: _Saved | None = None, colors=None,
                   colour_grad: bool = False):
    """dL/d opacities (M,) float64 given dL/d image (H, W, 3) (see the module docstring); ``saved`` from
    ``composite(..., save=True)`` with the same inputs skips the forward pass. ``colour_grad``: return
    ``(dL/d opacities, dL/d colours (M, 3))``."""
    op = np.ascontiguousarray(opacities, dtype=np.float32)
    cols = _colours(pairs, colors)
    if saved is None:
        saved = composite(pairs, op, background, early_stop=early_stop, save=True, colors=cols).saved
    grad = np.zeros(len(pairs.ids), np.float64)
    gcol = np.zeros((len(pairs.ids) if colour_grad else 0, 3), np.float64)
    gi = np.ascontiguousarray(grad_image, dtype=np.float64).reshape(-1, 3)
    _backward(pairs.start, pairs.splat, pairs.gauss, op, cols, np.asarray(background, np.float64),
              saved.t_final, saved.t_pair, gi, grad, gcol)
    return (grad, gcol) if colour_grad else grad


class _PairRender(torch.autograd.Function):
    @staticmethod
    def forward(ctx, opacities, colors, pairs, background, early_stop):
        op = opacities.detach().to("cpu", torch.float32).numpy()
        cols = None if colors is None else colors.detach().to("cpu", torch.float32).numpy()
        grads = opacities.requires_grad or (colors is not None and colors.requires_grad)
        out = composite(pairs, op, background, early_stop=early_stop, save=grads, colors=cols)
        ctx.pairs, ctx.background, ctx.early_stop, ctx.op, ctx.saved = pairs, background, early_stop, op, out.saved
        ctx.cols = cols
        return torch.from_numpy(out.image).to(opacities.device)

    @staticmethod
    def backward(ctx, grad_image):
        want_col = ctx.needs_input_grad[1]
        g = composite_grad(ctx.pairs, ctx.op, grad_image.detach().cpu().numpy(), ctx.background,
                           early_stop=ctx.early_stop, saved=ctx.saved, colors=ctx.cols, colour_grad=want_col)
        g_op, g_col = g if want_col else (g, None)
        to = dict(device=grad_image.device, dtype=grad_image.dtype)
        return (torch.from_numpy(g_op).to(**to), None if g_col is None else torch.from_numpy(g_col).to(**to),
                None, None, None)


def render_pairs(pairs: PixelPairs, opacities: torch.Tensor, background=(0, 0, 0), *,
                 early_stop: bool = False, colors: torch.Tensor | None = None) -> torch.Tensor:
    """(H, W, 3) float32 image, differentiable w.r.t. ``opacities`` (M,) (per visible splat) and, when
    given, ``colors`` (M, 3) (default: the pairs' own colours, not differentiated)."""
    return _PairRender.apply(opacities, colors, pairs, tuple(float(v) for v in background), early_stop)
