"""ConfSplatPrune's optimisation: Confident Splatting's Beta confidence, learned post hoc with geometry frozen.

Read from amirhossein-razlighi/Confident-Splatting (``confidence_utils.py``: ``confidence_values``,
``beta_entropy``; ``trainer.py``: ``create_splats_with_optimizers``, ``rasterize_splats``, the training
loss). Per splat j, raw parameters (a_j, b_j) initialised to **1** (``torch.ones``)::

    α_j = softplus(a_j) + 1e-6,   β_j = softplus(b_j) + 1e-6,   c_j = α_j / (α_j + β_j)
    rendered opacity = sigmoid(opacity_logit_j) · c_j                      (the "soft gate")
    loss = (1 − λ)·L1 + λ·(1 − SSIM) + λ_s·mean_j c_j + λ_e·mean_j H[Beta(α_j, β_j)]

with λ = 0.2, λ_s = 2e-3 and λ_e = 2e-3; their default ``beta_entropy_sign="minimize"`` **adds** the
entropy (confident, peaked Betas are favoured). Their optimiser is Adam per parameter group with
lr 1e-3 for both (batch size 1: lr·√1), eps 1e-15, betas (0.9, 0.999); that is the default here.

Pruning-only variant (DESIGN.md "Baselines"): every other parameter is frozen and the target of each
training view is the **unpruned** render of the same scene (computed once, no grad), so the gate learns
which splats the scene's own images need. Score = c. Left out: their saliency rank loss
(``rank_weight``) and the co-training of geometry, which need a training run.

Readings decided here:

* Rendering: the reference rasterizer's projection and α tests at reduced resolution
  (``train_longest_side``, default 128) through :mod:`renderers.pixel_pairs`, whose image and opacity gradient equal the tile
  rasterizer's (tested) at a fraction of the cost; black background; ``early_stop`` false as the
  harness renderers. SSIM is the 3DGS window (11×11, σ = 1.5, zero padding) of
  :func:`harness.metrics.ssim.ssim_map` with a differentiable banded-matmul blur (:func:`blur_matmul`),
  on unclamped images as their training loss.
* One view per step (their batch size 1), in a fixed order: one permutation of the training views per
  epoch from ``numpy.random.default_rng(seed)``. ``iterations`` steps, or fewer if the optimisation
  loop (set-up excluded) exceeds ``time_budget_s``; only the iteration budget is deterministic, so
  the defaults are sized for the iteration budget to bind.
* A splat invisible from every training view never enters a rendered pair, so its image gradient is
  exactly zero; only the sparsity and entropy terms move it (c falls from 0.5), while splats the
  images need rise above 0.5.
* ``threads``: torch intra-op threads while scoring (default 1, see :func:`renderers.pixel_pairs.torch_threads`).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
import torch
import torch.nn.functional as F

from harness.core.scene import GaussianScene
from harness.metrics.ssim import ssim_map
from renderers.pixel_pairs import (
    PixelPairs,
    build_pairs,
    composite,
    render_pairs,
    torch_threads,
)
from renderers.projection import SplatTensors, project_gaussians

log = logging.getLogger(__name__)

ENTROPY_SIGNS = {"minimize": 1.0, "maximize": -1.0}


@dataclass
class _View:
    pairs: PixelPairs
    ids: torch.Tensor  # (M,) scene index of the visible splats
    base: torch.Tensor  # (M,) sigmoid(opacity_logit) of those splats
    target: torch.Tensor  # (H, W, 3) unpruned render


@dataclass
class ConfidenceResult:
    confidence: np.ndarray  # (N,) float64, c = α/(α+β)
    losses: list[float] = field(default_factory=list)  # total loss of every step (its view)
    views: list[int] = field(default_factory=list)  # the view of every step
    iterations: int = 0
    setup_s: float = 0.0
    optimise_s: float = 0.0


def beta_gate(a: torch.Tensor, b: torch.Tensor):
    """(c, α, β) with α = softplus(a) + 1e-6, β = softplus(b) + 1e-6, c = α/(α + β)."""
    al = F.softplus(a) + 1e-6
    be = F.softplus(b) + 1e-6
    return al / (al + be), al, be


def prepare_views(scene: GaussianScene, cameras, longest_side: int, *, early_stop: bool = False,
                  device: str = "cpu") -> list[_View]:
    """Project every training view once, enumerate its pairs and render its unpruned target."""
    st = SplatTensors.from_scene(scene, device=device)
    views = []
    for cam in cameras:
        view = cam.resized(longest_side) if longest_side else cam
        with torch.no_grad():
            proj = project_gaussians(st, view)
        pairs = build_pairs(proj)
        target = torch.from_numpy(composite(pairs, early_stop=early_stop).image)
        views.append(_View(pairs, torch.from_numpy(pairs.ids), torch.from_numpy(pairs.opacities), target))
    return views


def _band(n: int, taps: np.ndarray, dtype) -> torch.Tensor:
    """(n, n) matrix K with (x K)_i = Σ_t taps[t]·x[i + t − r]: zero-padded 'same' correlation."""
    r = len(taps) // 2
    k = np.zeros((n, n))
    for t, v in enumerate(taps):
        idx = np.arange(n)
        src = idx + t - r
        ok = (src >= 0) & (src < n)
        k[src[ok], idx[ok]] = v
    return torch.as_tensor(k, dtype=dtype)


def blur_matmul(x: torch.Tensor, taps: np.ndarray) -> torch.Tensor:
    """:func:`harness.metrics.ssim.blur_torch` (separable, zero padding) as two banded matrix products:
    same values, and its backward is two more matmuls (conv2d's backward on 1-channel planes was a
    fifth of a ConfSplat step)."""
    h, w = x.shape[-2:]
    return _band(h, taps, x.dtype).T @ (x @ _band(w, taps, x.dtype))


def image_loss(img: torch.Tensor, target: torch.Tensor, lambda_dssim: float) -> torch.Tensor:
    """(1 − λ)·L1 + λ·(1 − SSIM) of (H, W, 3) images (3DGS / gsplat training loss)."""
    l1 = (img - target).abs().mean()
    x, y = img.permute(2, 0, 1)[None], target.permute(2, 0, 1)[None]
    ssim = ssim_map(x, y, blur=blur_matmul).mean()
    return (1.0 - lambda_dssim) * l1 + lambda_dssim * (1.0 - ssim)


def optimise_confidence(scene: GaussianScene, cameras, params=None, *, seed: int = 0,
                        device: str = "cpu") -> ConfidenceResult:
    """Learn the per-splat Beta gate (module docstring); ``params`` is a
    :class:`methods.confsplat.ConfSplatParams` (or a mapping of its fields; defaults for the rest)."""
    from methods.confsplat import ConfSplatParams

    p = (params if isinstance(params, ConfSplatParams) else ConfSplatParams.parse(params or {})).to_dict()
    if not cameras:
        raise ValueError("confsplat needs at least one training camera")
    early_stop = bool(p["early_stop"])
    t0 = time.perf_counter()
    with torch_threads(int(p["threads"])):
        views = prepare_views(scene, cameras, int(p["train_longest_side"]), early_stop=early_stop, device=device)
    result = ConfidenceResult(np.zeros(len(scene)), setup_s=time.perf_counter() - t0)

    n = len(scene)
    lam, lam_s = float(p["lambda_dssim"]), float(p["lambda_sparsity"])
    lam_e = float(p["lambda_entropy"]) * ENTROPY_SIGNS[p["entropy_sign"]]
    order_rng = np.random.default_rng(seed)
    deterministic = torch.are_deterministic_algorithms_enabled()
    torch.use_deterministic_algorithms(True, warn_only=True)
    try:
        with torch.random.fork_rng(devices=[]), torch_threads(int(p["threads"])):
            torch.manual_seed(seed)
            a = torch.full((n,), float(p["init"]), dtype=torch.float32, requires_grad=True)
            b = torch.full((n,), float(p["init"]), dtype=torch.float32, requires_grad=True)
            opt = torch.optim.Adam([a, b], lr=float(p["lr"]), eps=1e-15, betas=(0.9, 0.999))
            t1 = time.perf_counter()
            queue: list[int] = []
            for it in range(int(p["iterations"])):
                if it and time.perf_counter() - t1 > float(p["time_budget_s"]):
                    log.warning("confsplat: time budget %.0f s reached after %d of %d iterations",
                                float(p["time_budget_s"]), it, int(p["iterations"]))
                    break
                if not queue:
                    queue = [int(i) for i in order_rng.permutation(len(views))]
                vi = queue.pop(0)
                v = views[vi]
                result.views.append(vi)
                c, al, be = beta_gate(a, b)
                img = render_pairs(v.pairs, v.base * c[v.ids], early_stop=early_stop)
                loss = image_loss(img, v.target, lam) + lam_s * c.mean()
                if lam_e:
                    loss = loss + lam_e * torch.distributions.Beta(al, be).entropy().mean()
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                result.losses.append(float(loss.detach()))
                result.iterations = it + 1
            result.optimise_s = time.perf_counter() - t1
            log.info("confsplat: %d iterations in %.1f s after %.1f s of set-up (%d views)",
                     result.iterations, result.optimise_s, result.setup_s, len(views))
            with torch.no_grad():
                result.confidence = beta_gate(a, b)[0].double().numpy()
    finally:
        torch.use_deterministic_algorithms(deterministic)
    return result
