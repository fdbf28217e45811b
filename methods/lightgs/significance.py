"""LightGSPrune's computation: LightGaussian's global significance (pruning only, no fine-tuning).

Read from VITA-Group/LightGaussian (``prune.py``: ``prune_list``, ``calculate_v_imp_score``;
``prune_finetune.py``: ``--prune_type v_important_score``, ``--v_pow 0.1``; ``scene/gaussian_model.py``:
``prune_gaussians``) and its rasterizer's count pass (``renderCUDA_count`` in
Kevin-2017/compress-diff-gaussian-rasterization)::

    I_j  = Σ_views Σ_pixels o_j · T_j        (stored opacity times the transmittance before j, summed
                                               over every pixel where splat j passes the α tests)
    V_j  = s_x·s_y·s_z                       (activated scales: get_scaling = exp)
    V_ref = sort(V, descending)[int(0.9·N)]  (the value 90 % of the way down; no clamp anywhere)
    score_j = (V_j / V_ref)^v_pow · I_j,  v_pow = 0.1

Readings decided here:

* The count pass is graphdeco's forward with early termination: a pixel stops at the splat whose
  T·(1 − α) would fall below 1e-4, and that splat and the ones behind it get nothing. ``early_stop``
  (default true) keeps that; false counts every splat as the harness renderers composite them.
* Footprint: the harness renderers' ±radius box (the reference's ``footprint="box"``), not graphdeco's
  whole-tile evaluation (which also lets a splat paint faint pixels beyond its radius).
* Views: the context's training cameras, each resized to ``train_longest_side`` pixels on its long
  side (default 512, for speed; ``0`` keeps their own resolution). Σ over pixels scales with the pixel
  count, the same factor for every splat, so only small-splat rounding depends on it.
* (V_j / V_ref)^v_pow is evaluated as exp(v_pow·(Σ log s_j − log V_ref)) in float64, which ranks
  like LightGaussian's float32 product but cannot underflow to 0 for tiny splats.
* ``threads``: torch intra-op threads while scoring (default 1, see :func:`renderers.pixel_pairs.torch_threads`).

The accumulation is :func:`significance`, shared with the camera-free ``virtual-rig`` pruner
(:mod:`methods.virtualrig`), with three exact backends of the same sum:

* ``sweep`` (the CPU's): :mod:`renderers.sweep`, one front-to-back pass over the depth-sorted splats
  with a transmittance per pixel, the projection in numba — bit for bit the ``pairs`` result (same
  projection, same float operations in the same order per pixel and per splat), 4–11× faster on the
  same views, projection included (``harness bench methods --backends``, ``results/virtualrig/bench/``);
* ``pairs``: :mod:`renderers.pixel_pairs`, the reference rasterizer's projection and α tests
  compositing over enumerated (pixel, splat) pairs (numba, CPU; on CUDA only the projection runs on
  the GPU);
* ``reference``: the reference rasterizer's own per-splat statistics, torch on the context's device,
  so on CUDA the whole pass runs on the GPU: each view projected, then views of one size composited
  together (:func:`renderers.reference.composite_views`, as many per call as the device's memory
  allows), the sum kept on the device and read back once.

``pairs`` and ``reference`` agree to float rounding (the reference retires a tile once every pixel
has T < 1e-7 without early stop: effects below 1e-7). Measured on bonsai-7k-mini, 256×192 views, one
thread: pairs 0.18 s per view, the reference's eager CPU step 3.8 s (21×), so ``auto`` is ``sweep``
on the CPU and ``reference`` on any other device. None needs a renderer from the context.
"""

from __future__ import annotations

import numpy as np
import torch

from harness.core.scene import GaussianScene
from renderers import reference, sweep
from renderers.pixel_pairs import build_pairs, composite
from renderers.projection import SplatTensors, project_gaussians

V_REF_FRACTION = 0.9
BACKENDS = ("auto", "sweep", "pairs", "reference")


def resolve_backend(backend: str, device) -> str:
    """``sweep``, ``pairs`` or ``reference``: ``auto`` is the sweep on the CPU, the reference elsewhere (CUDA)."""
    if backend not in BACKENDS:
        raise ValueError(f"unknown significance backend {backend!r}; known: {', '.join(BACKENDS)}")
    if backend != "auto":
        return backend
    return "sweep" if torch.device(device).type == "cpu" else "reference"


def significance(scene: GaussianScene, cameras, *, longest_side: int = 512, early_stop: bool = True,
                 device: str = "cpu", backend: str = "auto", views_per_call: int | None = None) -> np.ndarray:
    """I_j = Σ_views Σ_pixels o_j·T_j over ``cameras`` (float64, (N,)); ``backend`` as in the module doc.

    ``views_per_call``: views the ``reference`` backend composites together (views of one size,
    :func:`renderers.reference.composite_views`); None sizes the batch by the device's memory
    (:func:`renderers.reference.views_per_call`). The sum equals the view-by-view one to float rounding."""
    use = resolve_backend(backend, device)
    views = [cam.resized(longest_side) if longest_side else cam for cam in cameras]
    if use == "sweep":
        if torch.device(device).type != "cpu":
            raise ValueError(f"the sweep backend runs on the CPU, not {device!r}")
        geom, total = sweep.Geometry(scene), np.zeros(len(scene), np.float64)
        for view in views:
            ids, sums = sweep.opacity_transmittance(geom, view, early_stop=early_stop)
            total[ids] += sums
        return total
    st = SplatTensors.from_scene(scene, device=device)
    if use == "reference":
        return _reference_sums(st, views, early_stop, views_per_call)
    total = np.zeros(len(scene), np.float64)
    for view in views:
        with torch.no_grad():
            pairs = build_pairs(project_gaussians(st, view))
        out = composite(pairs, early_stop=early_stop, stats=True)
        total[pairs.ids] += out.opacity_t  # a view lists each visible splat once
    return total


def _reference_sums(st: SplatTensors, views, early_stop: bool, views_per_call: int | None) -> np.ndarray:
    """The ``reference`` backend: views grouped by size (in their order), each group composited
    ``views_per_call`` at a time on the tensors' device, the sum kept there in float64."""
    acc = torch.zeros(len(st), dtype=torch.float64, device=st.device)
    by_size: dict[tuple[int, int], list] = {}
    for view in views:
        by_size.setdefault((int(view.width), int(view.height)), []).append(view)
    budget = reference.device_budget(st.device)
    for (width, height), group in by_size.items():
        step = views_per_call or reference.views_per_call(width, height, budget)
        for start in range(0, len(group), step):
            with torch.no_grad():
                projs = [project_gaussians(st, view) for view in group[start:start + step]]
                for out in reference.composite_views(projs, len(st), stats=True, early_stop=early_stop,
                                                     budget=budget):
                    acc += out.opacity_t.to(torch.float64)
    return acc.cpu().numpy()


def volume_factor(scales_log: np.ndarray, v_pow: float = 0.1) -> np.ndarray:
    """(V_j / V_ref)^v_pow with V = Π exp(scales_log), V_ref 90 % of the way down the descending sort."""
    log_v = scales_log.astype(np.float64).sum(axis=1)
    n = len(log_v)
    if n == 0:
        return np.zeros(0)
    log_ref = np.sort(log_v)[::-1][int(n * V_REF_FRACTION)]
    return np.exp(v_pow * (log_v - log_ref))
