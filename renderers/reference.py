"""Reference rasterizer: the classic 3DGS forward pass in plain torch (CPU or CUDA), tile-based, differentiable.

Pipeline (graphdeco ``FORWARD::render`` semantics):

1. :func:`renderers.projection.project_gaussians` → visible splats (means2d, conic, colour, opacity, radius).
2. Binning: splats are sorted front-to-back by view depth (stable, ties by scene index), every
   (tile, splat) pair whose footprint touches the tile is listed, and the list is stably sorted by tile,
   so each tile holds its splats in depth order.
3. Per pixel p with centre (i, j) and d = (i, j) − means2d (pixel-centre convention: see
   :mod:`renderers.projection`), front to back:
   ``power = −½(a dx² + c dy²) − b dx dy`` (skip if > 0), ``α = min(0.99, o·exp(power))`` (skip if
   α < 1/255), ``C += c·α·T``, ``T ← T(1 − α)``; finally ``C += T·bg``.

Conventions decided here (the GL renderer cannot reproduce graphdeco's quirks, so the defaults follow it):

* ``footprint="box"`` (default): a splat touches pixel (i, j) only if |i − x| ≤ r and |j − y| ≤ r — the
  pixels a GL quad covering ±radius rasterises. The image is then independent of the tile size.
  ``footprint="tile"`` is graphdeco's behaviour: every pixel of every 16×16 tile of ``getRect`` is
  evaluated, so a splat also paints (faint, α ≤ o·e^{-4.5}) pixels just beyond its radius.
* ``early_stop=False`` (default): no termination; every splat is composited. graphdeco stops a pixel
  when ``T·(1 − α) < 1e-4``, *excluding* the splat that would cross it (``early_stop=True`` reproduces
  that exactly, including its per-splat statistics). Without early stop, a tile whose every pixel has
  T < 1e-7 is retired: the rest could change colours by < 1e-7·max colour, below float32 noise of the
  GL blend.

Statistics (``stats=True``), summed over pixels for every splat that passed the α tests (and was not
stopped): α_i·T_i, o_i·T_i (LightGaussian's global significance: stored opacity times the transmittance
before the splat) and the hit count. T_i is the transmittance *before* splat i.

Memory: each step evaluates a (tiles × k × 256) block with tiles·k·256 ≤ ``budget`` elements, so peak
memory is bounded whatever the scene. With autograd on, every step is checkpointed (recomputed in
backward), so only per-step inputs are stored.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np
import torch
from torch.utils.checkpoint import checkpoint

from harness.cameras import Camera
from renderers.projection import TILE, Projected, SplatTensors, default_device, project_gaussians, tile_rects

ALPHA_MAX = 0.99
ALPHA_MIN = 1.0 / 255.0
T_EARLY_STOP = 1e-4
T_RETIRE = 1e-7
FOOTPRINTS = ("box", "tile")


@dataclass
class RasterOutput:
    image: torch.Tensor  # (H, W, 3)
    alpha_t: torch.Tensor | None = None  # (N,) Σ_pixels α_i T_i
    opacity_t: torch.Tensor | None = None  # (N,) Σ_pixels o_i T_i
    hits: torch.Tensor | None = None  # (N,) pixels where splat i passed the α tests


@dataclass
class _Bins:
    entries: torch.Tensor  # (E,) index into the Projected arrays, grouped by tile, depth order inside
    start: torch.Tensor  # (n_tiles,) first entry of each tile
    count: torch.Tensor  # (n_tiles,) number of entries
    gx: int
    gy: int


def bin_splats(proj: Projected, footprint: str = "box", tile: int = TILE) -> _Bins:
    """Tile lists in depth order. ``box``: tiles containing a pixel centre of the ±r box;
    ``tile``: graphdeco's ``getRect`` rectangle (16-px tiles only)."""
    w, h = proj.width, proj.height
    gx, gy = (w + tile - 1) // tile, (h + tile - 1) // tile
    dev = proj.means2d.device
    order = torch.sort(proj.depths.detach(), stable=True).indices
    m2d, r = proj.means2d.detach()[order], proj.radii.detach()[order]
    if footprint == "tile":
        if tile != TILE:
            raise ValueError("footprint='tile' reproduces graphdeco and needs 16-px tiles")
        x0, x1, y0, y1 = tile_rects(m2d, r, w, h)
    elif footprint == "box":
        def rng(c, size):
            lo = torch.ceil(c - r).clamp(min=0)
            hi = torch.floor(c + r).clamp(max=size - 1)
            empty = lo > hi
            a = torch.div(lo.clamp(max=size - 1), tile, rounding_mode="floor").long()
            b = torch.div(hi.clamp(min=0), tile, rounding_mode="floor").long() + 1
            return a, torch.where(empty, a, b)

        x0, x1 = rng(m2d[:, 0], w)
        y0, y1 = rng(m2d[:, 1], h)
    else:
        raise ValueError(f"footprint must be one of {FOOTPRINTS}, got {footprint!r}")
    wx = (x1 - x0).clamp(min=0)
    n_per = wx * (y1 - y0).clamp(min=0)
    total = int(n_per.sum())
    splat = torch.repeat_interleave(torch.arange(len(order), device=dev), n_per)
    first = torch.cumsum(n_per, 0) - n_per
    off = torch.arange(total, device=dev) - first[splat]
    wx_s = wx[splat]
    tiles = (y0[splat] + torch.div(off, wx_s, rounding_mode="floor")) * gx + x0[splat] + off % wx_s
    tiles, perm = torch.sort(tiles, stable=True)
    entries = order[splat[perm]]
    count = torch.bincount(tiles, minlength=gx * gy)
    start = torch.cumsum(count, 0) - count
    return _Bins(entries, start, count, gx, gy)


def _composite_step(mx, my, ca, cb, cc, op, col, rad, valid, px, py, pix_ok, t_in, done_in,
                    early_stop: bool, box: bool, stats: bool):
    """Composite k depth-ordered splats (B, k) over B tiles of P pixels (B, P), front to back.

    Returns the colour added (B, 3, P), the transmittance after (B, P), the done flags (B, P) and, when
    ``stats``, per-entry Σ_p α·T, Σ_p o·T and hit counts (B, k)."""
    dx = px[:, None, :] - mx[:, :, None]
    dy = py[:, None, :] - my[:, :, None]
    power = -0.5 * (ca[:, :, None] * dx * dx + cc[:, :, None] * dy * dy) - cb[:, :, None] * dx * dy
    alpha = torch.clamp_max(op[:, :, None] * torch.exp(power), ALPHA_MAX)
    mask = (power <= 0) & (alpha >= ALPHA_MIN) & valid[:, :, None] & pix_ok[:, None, :]
    if box:
        r = rad[:, :, None]
        mask &= (dx.abs() <= r) & (dy.abs() <= r)
    if early_stop:
        mask &= ~done_in[:, None, :]
    alpha = torch.where(mask, alpha, torch.zeros((), dtype=alpha.dtype, device=alpha.device))
    t_incl = t_in[:, None, :] * torch.cumprod(1.0 - alpha, dim=1)
    done = done_in
    if early_stop:
        # graphdeco: the splat whose T·(1−α) would drop below 1e-4 is not composited and ends the pixel;
        # T_incl is non-increasing, so "at or after the first crossing" is just T_incl < 1e-4.
        crossed = t_incl < T_EARLY_STOP
        mask = mask & ~crossed
        alpha = torch.where(crossed, torch.zeros((), dtype=alpha.dtype, device=alpha.device), alpha)
        done = done_in | crossed[:, -1, :]
        t_incl = t_in[:, None, :] * torch.cumprod(1.0 - alpha, dim=1)
    t_excl = torch.cat([t_in[:, None, :], t_incl[:, :-1, :]], dim=1)
    weight = alpha * t_excl
    added = torch.einsum("bkp,bkc->bcp", weight, col)
    out = (added, t_incl[:, -1, :], done)
    if stats:
        mt = torch.where(mask, t_excl, torch.zeros((), dtype=t_excl.dtype, device=t_excl.device))
        out += (weight.sum(-1), op * mt.sum(-1), mask.sum(-1))
    return out


def rasterize(scene, camera: Camera, background=(0, 0, 0), *, device=None,
              opacities: torch.Tensor | None = None, stats: bool = False,
              early_stop: bool = False, footprint: str = "box", tile: int = TILE,
              budget: int = 1 << 23) -> RasterOutput:
    """Render ``scene`` (a :class:`GaussianScene` or :class:`SplatTensors`) from ``camera``.

    ``opacities`` (N,) overrides sigmoid(opacity_logit) and may require grad; the image is then
    differentiable w.r.t. it (and w.r.t. any :class:`SplatTensors` field that requires grad).
    ``budget`` bounds the elements of one evaluation block (tiles × splats × pixels)."""
    if footprint not in FOOTPRINTS:
        raise ValueError(f"footprint must be one of {FOOTPRINTS}, got {footprint!r}")
    if isinstance(scene, SplatTensors):
        st = scene
    else:
        st = SplatTensors.from_scene(scene, device=default_device(device))
    proj = project_gaussians(st, camera, opacities=opacities)
    return composite(proj, len(st), background, stats=stats, early_stop=early_stop,
                     footprint=footprint, tile=tile, budget=budget)


def composite(proj: Projected, n_splats: int, background=(0, 0, 0), *, stats: bool = False,
              early_stop: bool = False, footprint: str = "box", tile: int = TILE,
              budget: int = 1 << 23) -> RasterOutput:
    """Rasterize already projected splats (see :func:`rasterize`); statistics are indexed by scene id
    (``n_splats`` long)."""
    dev, dtype = proj.means2d.device, proj.means2d.dtype
    w, h, npix = proj.width, proj.height, tile * tile
    bins = bin_splats(proj, footprint, tile)
    n_tiles = bins.gx * bins.gy
    zero = torch.zeros((), dtype=dtype, device=dev)
    box = footprint == "box"
    grad = torch.is_grad_enabled() and any(
        t.requires_grad for t in (proj.means2d, proj.conics, proj.colors, proj.opacities))
    m_vis = len(proj)
    acc = [torch.zeros(m_vis, dtype=dtype, device=dev) for _ in range(2)] if stats else None
    hits = torch.zeros(m_vis, dtype=torch.long, device=dev) if stats else None

    lin = torch.arange(npix, device=dev)
    act = torch.nonzero(bins.count > 0).squeeze(1)
    t_act = torch.ones(len(act), npix, dtype=dtype, device=dev)
    done_act = torch.zeros(len(act), npix, dtype=torch.bool, device=dev)
    color = torch.zeros(n_tiles, 3, npix, dtype=dtype, device=dev)
    fin_tiles, fin_t = [], []
    step = partial(_composite_step, early_stop=early_stop, box=box, stats=stats)
    pos = 0
    while len(act):
        b = len(act)
        k = max(1, min(int(bins.count[act].max()) - pos, budget // (b * npix)))
        slot = pos + torch.arange(k, device=dev)
        valid = slot[None, :] < bins.count[act][:, None]
        idx = torch.where(valid, bins.start[act][:, None] + slot[None, :], torch.zeros_like(slot[None, :]))
        s = bins.entries[idx]
        tx, ty = act % bins.gx, torch.div(act, bins.gx, rounding_mode="floor")
        px = (tx[:, None] * tile + lin % tile).to(dtype)
        py = (ty[:, None] * tile + torch.div(lin, tile, rounding_mode="floor")).to(dtype)
        pix_ok = (px < w) & (py < h)
        args = (proj.means2d[s, 0], proj.means2d[s, 1], proj.conics[s, 0], proj.conics[s, 1],
                proj.conics[s, 2], proj.opacities[s], proj.colors[s], proj.radii[s], valid, px, py, pix_ok,
                t_act, done_act)
        if grad:
            out = checkpoint(step, *args, use_reentrant=False)
        else:
            out = step(*args)
        added, t_act, done_act = out[:3]
        color = color.index_add(0, act, added) if grad else color.index_add_(0, act, added)
        if stats:
            sflat = s[valid]
            acc[0].index_add_(0, sflat, out[3][valid].detach())
            acc[1].index_add_(0, sflat, out[4][valid].detach())
            hits.index_add_(0, sflat, out[5][valid])
        pos += k
        with torch.no_grad():
            live = torch.where(pix_ok, t_act, zero)
            if early_stop:  # pixels outside the image count as done, as in graphdeco
                retired = ~(pix_ok & ~done_act).any(1)
            else:
                retired = ~(live.amax(1) >= T_RETIRE)
            still = (bins.count[act] > pos) & ~retired
        fin_tiles.append(act[~still])
        fin_t.append(t_act[~still])
        act, t_act, done_act = act[still], t_act[still], done_act[still]

    trans = torch.ones(n_tiles, npix, dtype=dtype, device=dev)
    if fin_tiles:
        trans = trans.index_copy(0, torch.cat(fin_tiles), torch.cat(fin_t))
    bg = torch.as_tensor(np.asarray(background, dtype=np.float64), dtype=dtype, device=dev)
    color = color + trans[:, None, :] * bg[None, :, None]
    image = color.reshape(bins.gy, bins.gx, 3, tile, tile).permute(0, 3, 1, 4, 2)
    image = image.reshape(bins.gy * tile, bins.gx * tile, 3)[:h, :w]
    if not stats:
        return RasterOutput(image)

    def full(v):
        out = torch.zeros(n_splats, dtype=v.dtype, device=dev)
        return out.index_put_((proj.ids,), v)

    return RasterOutput(image, full(acc[0]), full(acc[1]), full(hits))


class ReferenceRenderer:
    """The renderer-contract wrapper: ``render(scene, camera, background) -> (H, W, 3) float32``.

    Defaults match the GL renderer (``footprint="box"``, ``early_stop=False``); pass
    ``footprint="tile", early_stop=True`` for graphdeco's exact behaviour."""

    name = "reference"

    def __init__(self, device=None, *, early_stop: bool = False, footprint: str = "box"):
        self.device = default_device(device)
        self.early_stop = early_stop
        self.footprint = footprint

    def render(self, scene, camera: Camera, background=(0, 0, 0)) -> np.ndarray:
        with torch.no_grad():
            out = rasterize(scene, camera, background, device=self.device,
                            early_stop=self.early_stop, footprint=self.footprint)
        return out.image.to(torch.float32).cpu().numpy()

    def close(self) -> None:
        """Nothing to release (kept for the renderer contract)."""
