"""``harness plan --estimate --calibrate``: measure the main unit costs here, in a few seconds.

On the largest small real scene at hand (bonsai-7k-mini if fetched, else the shared playbot or
grape-small), CPU seconds of this process (all its threads: core-seconds) of

* one GL render at two sizes (128 and 1024 px longest side, best of two each): the per-pixel term
  is the difference over the pixel difference, the per-splat term what is left at 128 px;
* one SSIM and one PSNR pass at 384 px, and — when the LPIPS-VGG weights are present — one LPIPS
  reference-feature pass and one cached pass at 384 px;
* one ``betadesc`` score of the scene (per splat; the other camera-free methods keep their
  benchmark ratios to it).

Camera-aware scoring (minutes) is not measured: its multiple of a training render stays the
benchmark's. Each measured unit replaces the benchmark's, and its source says so. Like a run's
worker on a machine with as many workers as cores, it measures with one thread (torch, OpenMP,
llvmpipe): on a busy machine, idle threads spinning for work would count as CPU time.
"""

from __future__ import annotations

import contextlib
import os
import time

import numpy as np

from harness.run.unit_costs import UnitCosts


def _cpu(fn, repeats: int = 2, clock=time.process_time) -> float:
    """The least ``clock`` seconds of ``repeats`` calls of ``fn`` (CPU seconds of this process by default)."""
    best = float("inf")
    for _ in range(repeats):
        t0 = clock()
        fn()
        best = min(best, clock() - t0)
    return best


def _scene():
    from harness.io import datasets
    from harness.io.scenes import load_scene

    for name, lod in (("bonsai-7k-mini", None), ("playbot", 2), ("grape-small", None)):
        path = datasets.scene_path(name)
        if path.exists():
            return name, load_scene(path, lod=lod)
    return None, None


@contextlib.contextmanager
def one_thread():
    """Within the block, torch, OpenMP, llvmpipe and numba use one thread (torch's count restored
    after), as a study's one-core worker does."""
    import torch

    before = torch.get_num_threads()
    for var in ("OMP_NUM_THREADS", "LP_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ[var] = "1"
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def calibrate(costs: UnitCosts, log=print) -> UnitCosts:
    """Measure the units above and write them into ``costs`` (returned); what cannot be measured
    here (no scene, no GL, no LPIPS weights) keeps its benchmark value and adds a note."""
    with one_thread():
        return _calibrate(costs, log)


def _calibrate(costs: UnitCosts, log) -> UnitCosts:
    name, scene = _scene()
    if scene is None:
        costs.notes.append("--calibrate: no real scene here (harness fetch): benchmark values kept")
        return costs
    tag = f"--calibrate on {name} ({len(scene):,} splats)"
    from harness.views import rigs

    cam = rigs.make_rig("auto", scene, n_train=0, n_test=1, longest_side=384).test[0]
    small, big = cam.resized(128), cam.resized(1024)
    try:
        from renderers import get_renderer

        gl = get_renderer("gl")
        gl.render(scene, small)  # context, shaders
        t_small = _cpu(lambda: gl.render(scene, small))
        t_big = _cpu(lambda: gl.render(scene, big))
        px_small, px_big = small.width * small.height, big.width * big.height
        costs.render_px = max(t_big - t_small, 0.0) / (px_big - px_small)
        costs.render_splat = max(t_small - costs.render_px * px_small, 0.0) / len(scene)
        costs.pack_splat = min(_cpu(lambda: gl.pack(scene, small)) / len(scene), costs.render_splat)
        costs.sources["render_px"] = costs.sources["render_splat"] = f"{tag}: GL render at 128 and 1024 px"
        costs.sources["pack_splat"] = f"{tag}: a view packed (projection, sort)"
        img = np.asarray(gl.render(scene, cam), np.float32)
    except Exception as err:  # no GL here: the benchmark's render units stay
        costs.notes.append(f"--calibrate: GL render failed ({type(err).__name__}: {err}); benchmark values kept")
        img = np.random.default_rng(0).random((cam.height, cam.width, 3), dtype=np.float32)
    other = np.clip(img + 0.01, 0, 1).astype(np.float32)
    from harness.metrics.psnr import psnr
    from harness.metrics.ssim import ssim

    px = img.shape[0] * img.shape[1]
    costs.ssim_px = _cpu(lambda: ssim(img, other)) / px
    costs.psnr_px = _cpu(lambda: psnr(img, other)) / px
    costs.sources["ssim_px"] = costs.sources["psnr_px"] = f"{tag}: one pass at {img.shape[1]}×{img.shape[0]}"
    _lpips(costs, img, other, tag)
    try:
        from methods.registry import PruneContext, get_pruner

        spec = get_pruner("betadesc")
        spec.score(scene.subset(np.arange(min(len(scene), 2000))), PruneContext())  # numba's first compile
        unit = _cpu(lambda: spec.score(scene, PruneContext()), 1) / len(scene)
        old = costs.score_splat.get("betadesc")
        if old:
            costs.score_splat = {k: v * unit / old for k, v in costs.score_splat.items()}
        costs.score_splat["betadesc"] = unit
        costs.sources["score[betadesc]"] = f"{tag}: one score (other camera-free methods scaled with it)"
    except Exception as err:
        costs.notes.append(f"--calibrate: betadesc scoring failed ({type(err).__name__}); benchmark values kept")
    log(f"calibrated on {name}: render {costs.render_splat * 1e6:.3g} µs/splat + {costs.render_px * 1e6:.3g} µs/px")
    return costs


def _lpips(costs: UnitCosts, img, other, tag: str) -> None:
    from harness.metrics.lpips_weights import weights_path

    if not weights_path().is_file():
        costs.notes.append("--calibrate: LPIPS-VGG weights are missing; LPIPS keeps its benchmark cost")
        return
    from harness.metrics.suite import MetricSuite

    a, b = img, other
    suite = MetricSuite(names=("lpips",), device="cpu", max_in_memory=1)
    suite.reference("warm", a)
    suite.score("warm", b)
    px = a.shape[0] * a.shape[1]
    costs.lpips_ref_px = _cpu(lambda: suite.reference("v", a), 1) / px
    costs.lpips_px = _cpu(lambda: suite.score("v", b)) / px
    costs.sources["lpips_px"] = costs.sources["lpips_ref_px"] = f"{tag}: LPIPS at {a.shape[1]}×{a.shape[0]}"
