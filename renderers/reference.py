"""Reference rasterizer: the classic 3DGS forward pass in plain torch (CPU or CUDA), tile-based, differentiable.

Pipeline (graphdeco ``FORWARD::render`` semantics):

1. :func:`renderers.projection.project_gaussians` → visible splats (means2d, conic, colour, opacity, radius).
2. Binning (:mod:`renderers.binning`): splats are sorted front-to-back by view depth (stable, ties by
   scene index), every (tile, splat) pair whose footprint touches the tile is listed, and the list is
   stably sorted by tile, so each tile holds its splats in depth order.
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

Execution: tiles of 8×8 px for the box footprint (the image does not depend on the tile size; small
splats waste fewer evaluations than with 16×16), 16×16 for the tile footprint. Each round evaluates a
(tiles × k × pixels) block for all still-active tiles, k = the median remaining list length (≥ 8),
capped so that the block holds at most ``budget`` elements — peak memory is bounded whatever the scene
(~10 float temporaries of that size). Transmittance inside a block is a cumulative product along k,
carried between rounds. With autograd on, big renders checkpoint every round (recomputed in
backward), so only the per-round inputs are kept. Big CPU renders without autograd run the block step through
``torch.compile`` (see :func:`rasterize`). :func:`composite_views` stacks the tiles of several views of
one size into the same rounds (a GPU runs a batch of views in the kernel launches of one); on CUDA
:func:`device_budget` sizes the blocks by free memory and :func:`views_per_call` the batch.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from functools import partial

import numpy as np
import torch
from torch.utils import checkpoint as ckpt_util

from harness.core.cameras import Camera
from renderers.binning import FOOTPRINTS, Bins, bin_splats
from renderers.projection import (
    TILE,
    Projected,
    SplatTensors,
    default_device,
    project_gaussians,
)

log = logging.getLogger(__name__)

ALPHA_MAX = 0.99
ALPHA_MIN = 1.0 / 255.0
T_EARLY_STOP = 1e-4
T_RETIRE = 1e-7


@dataclass
class RasterOutput:
    image: torch.Tensor  # (H, W, 3)
    alpha_t: torch.Tensor | None = None  # (N,) Σ_pixels α_i T_i
    opacity_t: torch.Tensor | None = None  # (N,) Σ_pixels o_i T_i
    hits: torch.Tensor | None = None  # (N,) pixels where splat i passed the α tests
    alpha: torch.Tensor | None = None  # (H, W) accumulated opacity 1 − T of each pixel


def _composite_step(ent, valid, cols, rows, col_ok, row_ok, t_in, done_in, early_stop: bool, box: bool, stats: bool):
    """Composite k depth-ordered splats over B tiles of T×T pixels (P = T², row-major), front to back.

    ``ent`` (B, k, 10) packs per entry (mx, my, −a/2, −b, −c/2, o, r, colour); ``valid`` (B, k) marks
    real entries; ``cols``/``rows`` (B, T) are the tile's pixel-centre x and y, ``col_ok``/``row_ok``
    (B, T) their in-image flags; ``t_in``/``done_in`` (B, P) the transmittance and graphdeco done flags so far.
    The offsets, the box test and two of the three quadratic terms are separable in x and y, so they
    are evaluated on (B, k, T) and only combined on (B, k, P). Returns the colour added (B, 3, P), T
    and done after, and, when ``stats``, per-entry Σ_p α·T, Σ_p o·T and hit counts (B, k)."""
    mx, my, ha, nb, hc, op, rad = (ent[..., i, None] for i in range(7))
    dx = cols[:, None, :] - mx  # (B, k, T) along a row
    dy = rows[:, None, :] - my  # (B, k, T) along a column
    # −½(a dx² + c dy²) − b dx dy, laid out (B, k, row, col) → (B, k, P)
    power = ((hc * dy * dy)[..., :, None] + (ha * dx * dx)[..., None, :]
             + (nb * dy)[..., :, None] * dx[..., None, :]).flatten(-2)
    alpha = torch.clamp_max(op * torch.exp(power), ALPHA_MAX)
    in_x = valid[:, :, None] & col_ok[:, None, :]
    in_y = valid[:, :, None] & row_ok[:, None, :]
    if box:
        in_x, in_y = in_x & (dx.abs() <= rad), in_y & (dy.abs() <= rad)
    support = (in_y[..., :, None] & in_x[..., None, :]).flatten(-2)
    mask = (power <= 0) & (alpha >= ALPHA_MIN) & support
    if early_stop:
        mask &= ~done_in[:, None, :]
    nil = torch.zeros((), dtype=alpha.dtype, device=alpha.device)
    alpha = torch.where(mask, alpha, nil)
    t_incl = t_in[:, None, :] * torch.cumprod(1.0 - alpha, dim=1)
    done = done_in
    if early_stop:
        # graphdeco: the splat whose T·(1−α) would drop below 1e-4 is not composited and ends the pixel;
        # T_incl is non-increasing, so "at or after the first crossing" is just T_incl < 1e-4.
        crossed = t_incl < T_EARLY_STOP
        mask = mask & ~crossed
        alpha = torch.where(crossed, nil, alpha)
        done = done_in | crossed[:, -1, :]
        t_incl = t_in[:, None, :] * torch.cumprod(1.0 - alpha, dim=1)
    t_excl = torch.cat([t_in[:, None, :], t_incl[:, :-1, :]], dim=1)
    weight = alpha * t_excl
    added = torch.einsum("bkp,bkc->bcp", weight, ent[..., 7:10])
    out = (added, t_incl[:, -1, :], done)
    if stats:
        mt = torch.where(mask, t_excl, nil)
        out += (weight.sum(-1), op[..., 0] * mt.sum(-1), mask.sum(-1))
    return out


_STEPS: dict = {}
_COMPILE_BROKEN: list = []
#: evaluations (entries × pixels per tile) from which ``compiled=None`` compiles the CPU step
AUTO_COMPILE_MIN = 1 << 26
#: evaluations from which ``checkpoint=None`` recomputes blocks in backward instead of keeping them
#: (~10 saved floats per evaluation: 2^25 evaluations ≈ 1.3 GB)
AUTO_CHECKPOINT_MIN = 1 << 25


def _step_function(early_stop: bool, box: bool, stats: bool, compiled: bool):
    """:func:`_composite_step` with its flags bound; ``compiled`` wraps it in ``torch.compile`` (inductor
    fuses the ~25 element-wise passes into one loop: about 4× less CPU time per element here)."""
    key = (early_stop, box, stats, compiled)
    if key not in _STEPS:
        fn = partial(_composite_step, early_stop=early_stop, box=box, stats=stats)
        _STEPS[key] = torch.compile(fn, dynamic=True) if compiled else fn
    return _STEPS[key]


def _run_step(step, eager, args, grad: bool, ckpt: bool):
    if grad:
        return ckpt_util.checkpoint(step, *args, use_reentrant=False) if ckpt else step(*args)
    if step is eager:
        return step(*args)
    try:
        return step(*args)
    except Exception as err:  # noqa: BLE001 -- no C++ compiler, unsupported platform...: the eager step is the same math
        log.warning("torch.compile of the reference rasterizer failed (%s); using eager mode", err)
        _COMPILE_BROKEN.append(str(err))
        return eager(*args)


#: device memory one evaluation of a block takes at most (~10 float32 temporaries, bool masks, stats)
BYTES_PER_EVALUATION = 96
#: evaluations of one block by default (~1.6 GB of temporaries at most)
DEFAULT_BUDGET = 1 << 24
#: most evaluations of one block however much memory the device has
MAX_BUDGET = 1 << 28
#: most views one :func:`composite_views` call of :func:`views_per_call` stacks (each keeps its image
#: and per-splat statistics until the call returns)
MAX_VIEWS = 16


def device_budget(device) -> int:
    """Evaluations of one block on ``device``: :data:`DEFAULT_BUDGET` off CUDA; on CUDA as many as a
    quarter of its free memory holds at :data:`BYTES_PER_EVALUATION` each, between the default and
    :data:`MAX_BUDGET`."""
    dev = torch.device(device)
    if dev.type != "cuda":
        return DEFAULT_BUDGET
    free, _ = torch.cuda.mem_get_info(dev)
    return int(min(MAX_BUDGET, max(DEFAULT_BUDGET, free // 4 // BYTES_PER_EVALUATION)))


def views_per_call(width: int, height: int, budget: int = DEFAULT_BUDGET, tile: int = 8) -> int:
    """Views of ``width × height`` that :func:`composite_views` takes at once: as many as keep all
    their tiles in one group whose blocks are ≥ 8 entries deep within ``budget`` (the call then
    runs the rounds of one view, not of several groups), at least 1, at most :data:`MAX_VIEWS`."""
    n_tiles = ((width + tile - 1) // tile) * ((height + tile - 1) // tile)
    return int(max(1, min(MAX_VIEWS, budget // (8 * tile * tile * n_tiles))))


def rasterize(scene, camera: Camera, background=(0, 0, 0), *, device=None,
              opacities: torch.Tensor | None = None, stats: bool = False,
              early_stop: bool = False, footprint: str = "box", tile: int | None = None,
              budget: int = DEFAULT_BUDGET, compiled: bool | None = None,
              checkpoint: bool | None = None) -> RasterOutput:
    """Render ``scene`` (a :class:`GaussianScene` or :class:`SplatTensors`) from ``camera``.

    ``opacities`` (N,) overrides sigmoid(opacity_logit) and may require grad; the image is then
    differentiable w.r.t. it (and w.r.t. any :class:`SplatTensors` field that requires grad).
    ``tile``: 16 for ``footprint="tile"`` (graphdeco); for ``"box"`` the image does not depend on it and
    8 (the default) wastes fewer evaluations on small splats. ``budget`` bounds the elements of one
    evaluation block (tiles × splats × pixels; ~10 float temporaries of that size live at once).
    ``compiled``: run the per-block step through ``torch.compile``; ``None`` = on the CPU, without
    autograd, for renders of at least :data:`AUTO_COMPILE_MIN` evaluations (same math, float rounding
    differs by ~1e-7; the first compile in a fresh cache takes about a minute). ``checkpoint``: with
    autograd, recompute each block in backward instead of keeping its intermediates; ``None`` = only
    for renders of at least :data:`AUTO_CHECKPOINT_MIN` evaluations."""
    if footprint not in FOOTPRINTS:
        raise ValueError(f"footprint must be one of {FOOTPRINTS}, got {footprint!r}")
    if isinstance(scene, SplatTensors):
        st = scene
    else:
        st = SplatTensors.from_scene(scene, device=default_device(device))
    proj = project_gaussians(st, camera, opacities=opacities)
    return composite(proj, len(st), background, stats=stats, early_stop=early_stop,
                     footprint=footprint, tile=tile, budget=budget, compiled=compiled, checkpoint=checkpoint)


def composite(proj: Projected, n_splats: int, background=(0, 0, 0), *, stats: bool = False,
              early_stop: bool = False, footprint: str = "box", tile: int | None = None,
              budget: int = DEFAULT_BUDGET, compiled: bool | None = None,
              checkpoint: bool | None = None) -> RasterOutput:
    """Rasterize already projected splats (see :func:`rasterize`); statistics are indexed by scene id
    (``n_splats`` long)."""
    return composite_views([proj], n_splats, background, stats=stats, early_stop=early_stop, footprint=footprint,
                           tile=tile, budget=budget, compiled=compiled, checkpoint=checkpoint)[0]


def composite_views(projs: list[Projected], n_splats: int, background=(0, 0, 0), *, stats: bool = False,
                    early_stop: bool = False, footprint: str = "box", tile: int | None = None,
                    budget: int = DEFAULT_BUDGET, compiled: bool | None = None,
                    checkpoint: bool | None = None) -> list[RasterOutput]:
    """:func:`composite` of several views of one size in one pass: their tiles are stacked (view v's
    tile t is tile ``v·n_tiles + t``) and every round evaluates a block over the active tiles of all
    of them, so a batch costs the rounds of its longest tile list, not the sum over views.

    Each view's result equals its own :func:`composite` to float rounding (bit for bit for a single
    view): only the block depth k, chosen over all the batch's tiles, changes where the
    transmittance's running product is carried between rounds, and the order of the statistics' sums."""
    sizes = {(p.width, p.height) for p in projs}
    if len(sizes) != 1:
        raise ValueError(f"composite_views needs views of one size, got {sorted(sizes)}")
    tile = tile or (TILE if footprint == "tile" else 8)
    first = projs[0]
    dev, dtype = first.means2d.device, first.means2d.dtype
    w, h, npix = first.width, first.height, tile * tile
    per_view = [bin_splats(p, footprint, tile) for p in projs]
    gx, gy = per_view[0].gx, per_view[0].gy
    n_tiles, lens = gx * gy, [len(p) for p in projs]
    offsets = np.concatenate([[0], np.cumsum(lens)]).tolist()
    entries = torch.cat([b.entries + off for b, off in zip(per_view, offsets)])
    count = torch.cat([b.count for b in per_view])
    bins = Bins(entries, torch.cumsum(count, 0) - count, count, gx, gy)
    grad = torch.is_grad_enabled() and any(
        t.requires_grad for p in projs for t in (p.means2d, p.conics, p.colors, p.opacities))
    if compiled is None:
        compiled = (dev.type == "cpu" and not grad and not _COMPILE_BROKEN
                    and len(bins.entries) * npix >= AUTO_COMPILE_MIN)
    if checkpoint is None:
        checkpoint = len(bins.entries) * npix >= AUTO_CHECKPOINT_MIN
    eager = _step_function(early_stop, footprint == "box", stats, compiled=False)
    step = _step_function(early_stop, footprint == "box", stats, compiled=bool(compiled) and not grad)
    packed = torch.cat([torch.cat([p.means2d, -0.5 * p.conics[:, :1], -p.conics[:, 1:2], -0.5 * p.conics[:, 2:],
                                   p.opacities[:, None], p.radii[:, None].to(dtype), p.colors], 1) for p in projs])
    acc = torch.zeros(3, len(packed), dtype=dtype, device=dev) if stats else None

    lin = torch.arange(tile, device=dev)

    def run_tiles(act):
        """Composite the tiles ``act`` to the end of their lists; returns [(tiles, colour, T)]."""
        local = act % n_tiles  # the tile within its view
        cols = ((local % bins.gx)[:, None] * tile + lin).to(dtype)
        rows = (torch.div(local, bins.gx, rounding_mode="floor")[:, None] * tile + lin).to(dtype)
        ok = ((rows < h)[:, :, None] & (cols < w)[:, None, :]).flatten(1)
        t_act = torch.ones(len(act), npix, dtype=dtype, device=dev)
        done = ~ok if early_stop else torch.zeros_like(ok)  # graphdeco: pixels outside the image are done
        c_act = torch.zeros(len(act), 3, npix, dtype=dtype, device=dev)
        fin, pos = [], 0
        while len(act):
            count = bins.count[act]
            # block depth: the median remaining list length (short lists are padded at most ~2×, long
            # ones continue next round), at least 8, capped by the memory budget
            rest = count - pos
            k = max(1, min(int(rest.max()), max(8, int(rest.median())), budget // (len(act) * npix)))
            slot = pos + torch.arange(k, device=dev)
            valid = slot[None, :] < count[:, None]
            s = bins.entries[torch.where(valid, bins.start[act][:, None] + slot[None, :], 0)]
            args = (packed[s], valid, cols, rows, cols < w, rows < h, t_act, done)
            out = _run_step(step, eager, args, grad, checkpoint)
            c_act, t_act, done = c_act + out[0], out[1], out[2]
            if stats:
                acc.index_add_(1, s[valid], torch.stack([o[valid].detach().to(dtype) for o in out[3:]]))
            pos += k
            with torch.no_grad():
                if early_stop:
                    retired = done.all(1)
                else:  # every in-image pixel below T_RETIRE
                    retired = ~(torch.where(ok, t_act, 0.0).amax(1) >= T_RETIRE)
                still = (count > pos) & ~retired
            gone, keep = torch.nonzero(~still).squeeze(1), torch.nonzero(still).squeeze(1)
            fin.append((act[gone], c_act.index_select(0, gone), t_act.index_select(0, gone)))
            act, cols, rows, ok, t_act, done, c_act = (
                x.index_select(0, keep) for x in (act, cols, rows, ok, t_act, done, c_act))
        return fin

    # tiles are independent: groups small enough that a block of ≥ 8 entries per tile fits the budget
    tiles_all = torch.nonzero(bins.count > 0).squeeze(1)
    group = max(1, budget // (8 * npix))
    fin = [f for g in range(0, len(tiles_all), group) for f in run_tiles(tiles_all[g:g + group])]

    color = torch.zeros(len(projs) * n_tiles, 3, npix, dtype=dtype, device=dev)
    trans = torch.ones(len(projs) * n_tiles, npix, dtype=dtype, device=dev)
    if fin:
        tiles = torch.cat([f[0] for f in fin])
        color = color.index_copy(0, tiles, torch.cat([f[1] for f in fin]))
        trans = trans.index_copy(0, tiles, torch.cat([f[2] for f in fin]))
    bg = torch.as_tensor(np.asarray(background, dtype=np.float64), dtype=dtype, device=dev)
    color = color + trans[:, None, :] * bg[None, :, None]
    outs = []
    for v, proj in enumerate(projs):
        view = slice(v * n_tiles, (v + 1) * n_tiles)
        image = color[view].reshape(gy, gx, 3, tile, tile).permute(0, 3, 1, 4, 2)
        image = image.reshape(gy * tile, gx * tile, 3)[:h, :w]
        alpha = (1.0 - trans[view]).reshape(gy, gx, tile, tile).permute(0, 2, 1, 3)
        alpha = alpha.reshape(gy * tile, gx * tile)[:h, :w]
        if not stats:
            outs.append(RasterOutput(image, alpha=alpha))
            continue
        sums = acc[:, offsets[v]:offsets[v + 1]]
        full = torch.zeros(3, n_splats, dtype=dtype, device=dev).index_copy(1, proj.ids, sums)
        outs.append(RasterOutput(image, full[0], full[1], full[2].round().long(), alpha=alpha))
    return outs


class ReferenceRenderer:
    """The renderer-contract wrapper: ``render(scene, camera, background) -> (H, W, 3) float32``.

    Defaults match the GL renderer (``footprint="box"``, ``early_stop=False``); pass
    ``footprint="tile", early_stop=True`` for graphdeco's exact behaviour."""

    #: what it can do beyond ``render`` (:func:`renderers.capabilities`)
    capabilities = frozenset({"alpha"})

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

    def render_with_alpha(self, scene, camera: Camera, background=(0, 0, 0)) -> tuple[np.ndarray, np.ndarray]:
        """``(image (H, W, 3), alpha (H, W))`` float32; alpha = 1 − T, the pixel's accumulated opacity
        (the image is ``C + T·background``)."""
        with torch.no_grad():
            out = rasterize(scene, camera, background, device=self.device,
                            early_stop=self.early_stop, footprint=self.footprint)
        return out.image.to(torch.float32).cpu().numpy(), out.alpha.to(torch.float32).cpu().numpy()

    def close(self) -> None:
        """Nothing to release (kept for the renderer contract)."""
