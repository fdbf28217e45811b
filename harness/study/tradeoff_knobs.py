"""Measurements behind ``harness bench tradeoff``: each speed/accuracy knob's cost and its error.

Every knob family is measured against its *most accurate* setting, taken in the same run:

* pruning knobs (BetaDescPrune descriptors) — ``voxel`` (fraction of the bounding-box diagonal; the
  finest is the reference), ``radius_voxels`` and ``max_nn`` (the neighbourhood; the largest is the
  reference). Error: 1 − Spearman ρ of the scores against the reference scores, and 1 − Jaccard of the
  removed sets at ratio 0.3 (|R ∩ R_ref| / |R ∪ R_ref|).
* evaluation knobs, on the scene pruned by 30 % with default BetaDescPrune, over the held-out views:
  ``resolution`` (render longest side; 1024 = the CTC setting is the reference), ``lpips_input``
  (images rendered at the reference resolution, area-downsampled before LPIPS; full size is the
  reference), ``lpips_precision`` (float32 reference, bfloat16 autocast), ``renderer`` (reference
  rasterizer in float64 as the reference, in float32, and GL). Error: |ΔPSNR|, |ΔSSIM|, |ΔLPIPS| of the
  per-view metrics (pruned vs unpruned render) against the reference setting's, averaged over views.

Time is measured twice: wall seconds and CPU seconds of the whole process (all threads, GL's llvmpipe
and torch included). On a shared machine the wall clock mostly measures the neighbours, so the
Pareto plot uses CPU seconds; both are reported. Costs are per scene (pruning) or per view
(evaluation: two renders and their metrics, or two LPIPS passes for the LPIPS knobs).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

PRUNE_FAMILIES = {
    "voxel": ("voxel", [0.005, 0.0075, 0.01, 0.015, 0.02, 0.04], 0.005),
    "radius_voxels": ("radius_voxels", [2.0, 3.0, 5.0, 8.0], 8.0),
    "max_nn": ("max_nn", [16, 32, 64, 100, 200], 200),
}
QUICK_PRUNE = {
    "voxel": ("voxel", [0.01, 0.02, 0.04], 0.01),
    "max_nn": ("max_nn", [16, 100], 100),
}


@dataclass
class Row:
    family: str
    setting: str
    reference: bool
    wall_s: float
    cpu_s: float
    errors: dict = field(default_factory=dict)


class Clock:
    """Wall and process-CPU seconds of a block: ``with Clock() as c: ...; c.wall, c.cpu``."""

    def __enter__(self):
        self._w, self._c = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc):
        self.wall = time.perf_counter() - self._w
        self.cpu = time.process_time() - self._c


def removed_jaccard(a: np.ndarray, b: np.ndarray, ratio: float = 0.3) -> float:
    """Jaccard index of the splats removed at ``ratio`` by scores ``a`` and ``b``."""
    from methods.targeting import select_by_ratio

    ra, rb = ~select_by_ratio(a, ratio).keep, ~select_by_ratio(b, ratio).keep
    union = int((ra | rb).sum())
    return 1.0 if union == 0 else int((ra & rb).sum()) / union


def prune_knobs(scene, families: dict, repeats: int = 1) -> tuple[list[Row], np.ndarray]:
    """Score ``scene`` with every setting of every family; returns rows and the default scores."""
    from scipy.stats import spearmanr

    from methods.registry import PruneContext, get_pruner

    spec = get_pruner("betadesc")
    spec.score(scene.subset(np.arange(min(len(scene), 2000))), PruneContext())  # JIT / import warm-up
    rows, default_scores = [], None
    for family, (param, values, ref) in families.items():
        scores = {}
        times = {}
        for v in [ref] + [x for x in values if x != ref]:
            samples = []
            for _ in range(repeats):
                with Clock() as c:
                    s = spec.score(scene, PruneContext(params={param: v}))
                samples.append((c.wall, c.cpu))
            scores[v] = s
            times[v] = tuple(np.median(np.asarray(samples), axis=0))
        for v in values:
            # identical scores correlate exactly 1; spearmanr's float arithmetic can return 1 − 1 ulp
            same = np.array_equal(scores[v], scores[ref])
            rho = 1.0 if same else float(spearmanr(scores[v], scores[ref]).statistic)
            rows.append(Row(family, f"{param}={v:g}", v == ref, *times[v],
                            {"1-spearman": 1.0 - rho, "1-jaccard@0.3": 1.0 - removed_jaccard(scores[v], scores[ref])}))
            if family == "voxel" and v == spec.parse_params().voxel:
                default_scores = scores[v]
    if default_scores is None:
        default_scores = spec.score(scene, PruneContext())
    return rows, default_scores


def _metric_errors(metrics: list[dict], ref: list[dict]) -> dict:
    """Mean |Δ| over views of PSNR (finite pairs only), SSIM, LPIPS."""
    out = {}
    for k in ("psnr", "ssim", "lpips"):
        d = [abs(m[k] - r[k]) for m, r in zip(metrics, ref)
             if k in m and k in r and np.isfinite(m[k]) and np.isfinite(r[k])]
        if d:
            out[f"|d{k.upper()}|"] = float(np.mean(d))
    return out


def downsample(img: np.ndarray, longest: int) -> np.ndarray:
    """Area-average ``img`` (H, W, 3) to longest side ``longest`` (PIL box filter, float32)."""
    from PIL import Image

    h, w = img.shape[:2]
    s = longest / max(h, w)
    if s >= 1:
        return img
    size = (max(16, round(w * s)), max(16, round(h * s)))
    chans = [np.asarray(Image.fromarray(img[..., c].astype(np.float32), mode="F").resize(size, Image.BOX))
             for c in range(3)]
    return np.stack(chans, -1).astype(np.float32)


class Evaluator:
    """Renders a scene and its pruned version from a set of views and scores the pair."""

    def __init__(self, scene, pruned, cameras, lpips_fp32, lpips_bf16):
        from renderers import get_renderer

        self.scene, self.pruned, self.cameras = scene, pruned, cameras
        self.gl = get_renderer("gl")
        self.lp = {"float32": lpips_fp32, "bfloat16": lpips_bf16}

    def render(self, kind: str, scene, cam) -> np.ndarray:
        import torch

        if kind == "gl":
            return self.gl.render(scene, cam)
        from renderers.projection import SplatTensors
        from renderers.reference import rasterize

        dtype = torch.float64 if kind == "reference-float64" else torch.float32
        with torch.no_grad():
            st = SplatTensors.from_scene(scene, device="cpu", dtype=dtype)
            return rasterize(st, cam).image.to(torch.float32).numpy()

    def metrics(self, ref_img, img, precision="float32", lpips_side=None) -> dict:
        from harness.metrics.psnr import psnr
        from harness.metrics.ssim import ssim

        a = downsample(ref_img, lpips_side) if lpips_side else ref_img
        b = downsample(img, lpips_side) if lpips_side else img
        return {"psnr": psnr(ref_img, img), "ssim": ssim(ref_img, img), "lpips": self.lp[precision](a, b)}

    def lpips_only(self, ref_img, img, precision="float32", lpips_side=None) -> float:
        a = downsample(ref_img, lpips_side) if lpips_side else ref_img
        b = downsample(img, lpips_side) if lpips_side else img
        return self.lp[precision](a, b)

    def close(self):
        self.gl.close()


def eval_knobs(ev: Evaluator, sides: list[int], lpips_sides: list[int], renderer_side: int) -> list[Row]:
    """Rows for the resolution, LPIPS input, LPIPS precision and renderer families."""
    rows = []
    full = max(sides)
    n = len(ev.cameras)
    per_side = {}
    for side in sorted(sides, reverse=True):
        ms, wall, cpu = [], 0.0, 0.0
        for cam in ev.cameras:
            c = cam.resized(side)
            with Clock() as k:
                a, b = ev.render("gl", ev.scene, c), ev.render("gl", ev.pruned, c)
                ms.append(ev.metrics(a, b))
            wall, cpu = wall + k.wall, cpu + k.cpu
            if side == full:
                per_side.setdefault("images", []).append((a, b))
        per_side[side] = ms
        rows.append(Row("resolution", f"{side}px", side == full, wall / n, cpu / n,
                        _metric_errors(ms, per_side[full])))
    images = per_side["images"]
    ref_lp = None
    for side in [full] + [s for s in sorted(lpips_sides, reverse=True) if s < full]:
        vals, wall, cpu = [], 0.0, 0.0
        for a, b in images:
            with Clock() as k:
                vals.append(ev.lpips_only(a, b, lpips_side=None if side == full else side))
            wall, cpu = wall + k.wall, cpu + k.cpu
        ref_lp = vals if side == full else ref_lp
        rows.append(Row("lpips_input", f"{side}px", side == full, wall / n, cpu / n,
                        {"|dLPIPS|": float(np.mean(np.abs(np.subtract(vals, ref_lp))))}))
    ref_prec = None
    for prec in ("float32", "bfloat16"):
        vals, wall, cpu = [], 0.0, 0.0
        for a, b in images:
            with Clock() as k:
                vals.append(ev.lpips_only(a, b, precision=prec))
            wall, cpu = wall + k.wall, cpu + k.cpu
        ref_prec = vals if prec == "float32" else ref_prec
        rows.append(Row("lpips_precision", prec, prec == "float32", wall / n, cpu / n,
                        {"|dLPIPS|": float(np.mean(np.abs(np.subtract(vals, ref_prec))))}))
    ref_ms, ref_imgs = None, None
    for kind in ("reference-float64", "reference-float32", "gl"):
        ms, imgs, wall, cpu = [], [], 0.0, 0.0
        for cam in ev.cameras:
            c = cam.resized(renderer_side)
            with Clock() as k:
                a, b = ev.render(kind, ev.scene, c), ev.render(kind, ev.pruned, c)
            wall, cpu = wall + k.wall, cpu + k.cpu
            ms.append(ev.metrics(a, b))
            imgs.append(a)
        if ref_ms is None:
            ref_ms, ref_imgs = ms, imgs
        err = _metric_errors(ms, ref_ms)
        from harness.metrics.psnr import mse, psnr_from_mse

        err["image PSNR vs float64 (dB)"] = float(np.mean([psnr_from_mse(mse(x, y)) if kind != "reference-float64"
                                                           else np.inf for x, y in zip(imgs, ref_imgs)]))
        rows.append(Row("renderer", kind, kind == "reference-float64", wall / n, cpu / n, err))
    return rows


def pareto_front(points: list[tuple[float, float]]) -> list[bool]:
    """Non-dominated flags for (time, error) pairs: no other point is ≤ in both and < in one."""
    flags = []
    for i, (t, e) in enumerate(points):
        dominated = any((t2 <= t and e2 <= e) and (t2 < t or e2 < e) for j, (t2, e2) in enumerate(points) if j != i)
        flags.append(not dominated)
    return flags
