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

Pruning-only variant (docs/decisions.md, "The baselines"): every other parameter is frozen and the target of each
training view is the **unpruned** render of the same scene (computed once, no grad), so the gate learns
which splats the scene's own images need. Score = c. Left out: the co-training of geometry and SH,
which needs a training run.

**Saliency rank loss** (their ``trainer.py``; two versions, both parameters here):

* saliency: after every backward, S_j += mean_{k,ch} |∂L/∂c^SH_{j,k,ch}| over the splat's K = (d+1)²
  SH coefficients (``sh0`` and ``shN`` grads). With frozen SH we compute it from the colour gradient of
  the pair renderer: colour_j = max(Σ_k Y_k(dir_j) c_{j,k} + ½, 0), so |∂L/∂c_{j,k,ch}| =
  |Y_k(dir_j)|·|∂L/∂colour_{j,ch}| (0 where the clamp is active), and the mean over (k, ch) is
  (mean_k |Y_k|)·(mean_ch |∂L/∂colour_ch|). Splats a view does not see get 0.
* every ``rank_interval`` (25) steps from ``rank_start_step``, *before* the step's backward: H = the
  K = min(``rank_pairs``, N) most salient splats, L = the K least salient (each sorted; ties by lowest
  index, where their ``topk`` is unspecified), paired by rank; loss += ``rank_weight`` ·
  mean_k relu(m + c_{L_k} − c_{H_k}); then the buffer is zeroed (the step's own saliency is added after).
  Weight 1.0, 2048 pairs. Margin m and start: **1.0 from step 0 in the code of the paper's era**
  (``e801512``, 2025-07-06; with c ∈ (0, 1) the hinge is always active: a constant push of 1/K per
  pair and step) — the default here — and **0.10 from step 1000 at HEAD** (``e7343b2``; HEAD's 1000 is
  a warm-up of their 30k joint steps, which a post-hoc run on a trained scene is past, and literally
  it would switch the loss off in a 600-step run). A rank step whose buffer is all zero (the very first
  at step 0) is skipped, as HEAD's guard does (the 2025 code would pair arbitrary tied splats).

  Two consequences worth knowing (both tested): with N ≤ ``rank_pairs`` every splat is in both halves
  and, the margin-1.0 hinge being always active, its −1/K and +1/K cancel exactly (a no-op on scenes
  under 2048 splats); and under Adam a rank step is a rare spike in a splat's gradient that inflates
  its second moment, so for splats whose other gradients are small (the unseen ones: only the
  regularisers) it *damps* the following steps — over ~100 steps they fall less far than without
  the loss, although each rank step's gradient points down for them.

Readings decided here:

* Rendering: the reference rasterizer's projection and α tests at reduced resolution
  (``train_longest_side``, default 128) through :mod:`renderers.pixel_pairs`, whose image, opacity
  and colour gradients equal the tile rasterizer's (tested) at a fraction of the cost; black
  background; ``early_stop`` false as the harness renderers. SSIM is the 3DGS window (11×11, σ = 1.5, zero padding) of
  :func:`harness.metrics.ssim.ssim_map` with a differentiable banded-matmul blur (:func:`blur_matmul`),
  on unclamped images as their training loss.
* One view per step (their batch size 1), in a fixed order: one permutation of the training views per
  epoch from ``numpy.random.default_rng(seed)``. Views are **not** batched per step, on any device:
  their ``Config`` has ``batch_size: int = 1`` ("Learning rates are scaled automatically"), and
  ``create_splats_with_optimizers`` turns a batch of B into another optimiser — lr·√B, eps 1e-15/√B,
  betas (1 − B·0.1, 1 − B·0.001) — with the comment "this would not make the training exactly
  equivalent"; the rank loss's saliency would also be summed per batch, not per view. So B > 1 is a
  different method from the one the study compares, and no parameter offers it. (The optimisation
  runs on the CPU's pixel pairs, :mod:`renderers.pixel_pairs`; only the set-up's projection uses
  the context's device.) ``iterations`` steps; no wall-clock budget by default.
  With ``time_budget_s`` set, fewer if the optimisation loop (set-up excluded) exceeds it: the result
  then records ``stopped_by_budget`` and the ``iterations`` done (a lower bound; logged as a warning).
* A splat invisible from every training view never enters a rendered pair, so its image gradient is
  exactly zero; only the sparsity and entropy terms move it (c falls from 0.5), while splats the
  images need rise above 0.5.
* ``threads``: torch intra-op threads of the set-up (projecting the training views: each splat's values
  depend on it alone, :mod:`renderers.projection`); the optimisation always runs on **one** thread.
  torch's CPU kernels of softplus, lgamma/digamma/polygamma (the Beta entropy and its gradient) compute
  the last elements of each thread's chunk with a scalar formula that differs in the last bit from the
  vectorised one, and its sums add chunk by chunk, so on more threads the learned confidences changed
  with the thread count (measured: 1, 2 and 8 threads gave three different score arrays on
  bonsai-7k-mini), and with ``threads: 0`` with the worker's ``--threads``.
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
from renderers.sh import sh_basis

log = logging.getLogger(__name__)

ENTROPY_SIGNS = {"minimize": 1.0, "maximize": -1.0}


@dataclass
class _View:
    pairs: PixelPairs
    ids: torch.Tensor  # (M,) scene index of the visible splats
    base: torch.Tensor  # (M,) sigmoid(opacity_logit) of those splats
    target: torch.Tensor  # (H, W, 3) unpruned render
    colors: torch.Tensor  # (M, 3) the pairs' colours (SH colour + ½, clamped at 0)
    sal_scale: torch.Tensor  # (M,) mean_k |Y_k(dir)| over the K SH coefficients (saliency factor)
    unclamped: torch.Tensor  # (M, 3) colour above the clamp at 0 (the SH gradient passes)


@dataclass
class ConfidenceResult:
    confidence: np.ndarray  # (N,) float64, c = α/(α+β)
    losses: list[float] = field(default_factory=list)  # total loss of every step (its view)
    views: list[int] = field(default_factory=list)  # the view of every step
    iterations: int = 0
    stopped_by_budget: bool = False
    rank_steps: int = 0  # rank-loss steps applied
    rank_losses: list[float] = field(default_factory=list)
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
        ids = torch.from_numpy(pairs.ids)
        dirs = st.means[ids.to(st.device)].double().cpu() - torch.as_tensor(view.center, dtype=torch.float64)
        dirs = dirs / torch.linalg.vector_norm(dirs, dim=-1, keepdim=True).clamp_min(1e-30)
        scale = sh_basis(dirs, st.sh_degree).abs().mean(dim=1).float()
        colors = torch.from_numpy(pairs.colors)
        views.append(_View(pairs, ids, torch.from_numpy(pairs.opacities), target, colors, scale, colors > 0))
    return views


def rank_pairs(saliency: torch.Tensor, k: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(H, L): the ``k`` most and least salient indices, each sorted, ties by lowest index."""
    k = min(k, saliency.numel())
    hi = torch.sort(saliency, descending=True, stable=True).indices[:k]
    lo = torch.sort(saliency, stable=True).indices[:k]
    return hi, lo


def view_saliency(v: _View, colour_grad: torch.Tensor) -> torch.Tensor:
    """mean_{k,ch} |∂L/∂c^SH_{j,k,ch}| of the view's visible splats from dL/dcolour (M, 3) (module doc)."""
    return (colour_grad.abs() * v.unclamped).mean(dim=1) * v.sal_scale


def rank_loss(c: torch.Tensor, saliency: torch.Tensor, k: int, margin: float) -> torch.Tensor:
    """mean_k relu(margin + c[L_k] − c[H_k]) over the rank-paired most/least salient splats."""
    hi, lo = rank_pairs(saliency, k)
    return F.relu(margin + c[lo] - c[hi]).mean()


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
        with torch.random.fork_rng(devices=[]), torch_threads(1):  # the thread count changes the sums
            torch.manual_seed(seed)
            a = torch.full((n,), float(p["init"]), dtype=torch.float32, requires_grad=True)
            b = torch.full((n,), float(p["init"]), dtype=torch.float32, requires_grad=True)
            opt = torch.optim.Adam([a, b], lr=float(p["lr"]), eps=1e-15, betas=(0.9, 0.999))
            rank_w = float(p["rank_weight"])
            saliency = torch.zeros(n, dtype=torch.float64)
            budget = p["time_budget_s"]
            t1 = time.perf_counter()
            queue: list[int] = []
            for it in range(int(p["iterations"])):
                if it and budget is not None and time.perf_counter() - t1 > float(budget):
                    result.stopped_by_budget = True
                    log.warning("confsplat: time budget %.0f s reached after %d of %d iterations: the result is "
                                "a lower bound (%d iterations)", float(budget), it, int(p["iterations"]), it)
                    break
                if not queue:
                    queue = [int(i) for i in order_rng.permutation(len(views))]
                vi = queue.pop(0)
                v = views[vi]
                result.views.append(vi)
                c, al, be = beta_gate(a, b)
                colors = v.colors.clone().requires_grad_(True) if rank_w > 0 else None
                img = render_pairs(v.pairs, v.base * c[v.ids], early_stop=early_stop, colors=colors)
                loss = image_loss(img, v.target, lam) + lam_s * c.mean()
                if lam_e:
                    loss = loss + lam_e * torch.distributions.Beta(al, be).entropy().mean()
                if rank_w > 0 and it >= int(p["rank_start_step"]) and it % int(p["rank_interval"]) == 0:
                    if bool((saliency > 0).any()):
                        lr_ = rank_loss(c, saliency, int(p["rank_pairs"]), float(p["rank_margin"]))
                        loss = loss + rank_w * lr_
                        result.rank_steps += 1
                        result.rank_losses.append(float(lr_.detach()))
                    saliency.zero_()
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                if colors is not None:
                    saliency.index_add_(0, v.ids, view_saliency(v, colors.grad).double())
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
