"""``harness plan --estimate --calibrate``: measure the main unit costs here, in a few seconds.

On the largest small real scene at hand (bonsai-7k-mini if fetched, else the shared playbot or
grape-small), CPU seconds of this process (all its threads: core-seconds) of

* the render units of one GL view at 256 px, as ``harness bench calibrate`` measures them
  (:func:`render_units`: per splat in front, visible, drawn, per fragment and per pixel);
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
from harness.run.view_coverage import Coverage


def _best(fn, repeats: int, clock=time.perf_counter) -> float:
    """Least ``clock`` seconds of ``repeats`` calls of ``fn`` after a warm-up call."""
    fn()
    return _cpu(fn, repeats, clock=clock)


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
    try:
        from renderers import get_renderer

        gl = get_renderer("gl")
        units, _, seen = render_units(gl, scene, cam.resized(256), 1, time.process_time)
        for k, v in units.items():
            setattr(costs, k, v)
            costs.sources[k] = f"{tag}: GL view packed, zoomed, drawn empty, at 256 and 512 px"
        costs.seen = Coverage(**seen)
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


def render_units(gl, scene, cam, repeats: int, clock) -> tuple[dict, dict, dict]:
    """(units, seconds, the view's coverage as a dict) of the GL renderer ``gl`` on ``scene`` seen by
    ``cam``, each timing the best of ``repeats`` after a warm-up by ``clock``: the view packed, and
    packed 16× zoomed in (as many splats in front, few visible) → ``front_splat``, ``visible_splat``;
    a packing of no splat drawn → ``image_px``; the view drawn at its size and at twice it →
    ``draw_splat``, ``fragment_px`` (:mod:`harness.run.view_coverage` counts the splats and
    fragments); ``render_px`` and ``render_splat``/``pack_splat``, the plain model's, from the same
    timings (:mod:`harness.benchmarks.calibrate`)."""
    from dataclasses import asdict, replace

    from harness.run.view_coverage import coverage
    from renderers.gl import PackedView

    n, big, zoom = len(scene), cam.resized(2 * max(cam.width, cam.height)), replace(cam, fx=16 * cam.fx, fy=16 * cam.fy)
    seen, seen_big, seen_zoom = coverage(scene, cam), coverage(scene, big), coverage(scene, zoom)
    t_pack = _best(lambda: gl.pack(scene, cam), repeats, clock)
    t_zoom = _best(lambda: gl.pack(scene, zoom), repeats, clock)
    view, view_big = gl.pack(scene, cam), gl.pack(scene, big)
    empty = PackedView(view.records[:0], view.ids[:0], view.width, view.height)
    t_empty = _best(lambda: gl.draw(empty), repeats, clock)
    t_draw = _best(lambda: gl.draw(view), repeats, clock)
    t_big = _best(lambda: gl.draw(view_big), repeats, clock)
    px, px_big = cam.width * cam.height, big.width * big.height
    # packing: c_front·front + c_vis·visible, of the view and of its 16× zoom (as many splats in front, few visible)
    c_front, c_vis = _solve([[n * seen.front, n * seen.visible], [n * seen_zoom.front, n * seen_zoom.visible]],
                            [t_pack, t_zoom])
    # drawing: c_draw·visible + c_frag·fragments + c_img·W·H, at the size and at twice it
    image_px = t_empty / px
    c_draw, c_frag = _solve([[n * seen.visible, seen.overdraw * px],
                             [n * seen_big.visible, seen_big.overdraw * px_big]],
                            [t_draw - image_px * px, t_big - image_px * px_big])
    render_px = max(t_big - t_draw, 0.0) / (px_big - px)
    units = {"render_px": render_px, "render_splat": (t_pack + max(t_draw - render_px * px, 0.0)) / n,
             "pack_splat": t_pack / n, "front_splat": c_front, "visible_splat": c_vis, "draw_splat": c_draw,
             "fragment_px": c_frag, "image_px": image_px}
    seconds = {"pack": t_pack, "pack_zoomed": t_zoom, "draw_empty": t_empty, "draw_full": t_draw, "draw_double": t_big}
    return units, seconds, asdict(seen)


def _solve(a, b) -> tuple[float, float]:
    """The non-negative (x, y) with ``a @ (x, y) ≈ b`` (the least-squares solution, a negative part
    set to 0 and the other refitted: a unit cost is never negative)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    x = np.linalg.lstsq(a, b, rcond=None)[0]
    if (x >= 0).all():
        return float(x[0]), float(x[1])
    j = int(np.argmax(x))
    out = [0.0, 0.0]
    out[j] = max(float(a[:, j] @ b / (a[:, j] @ a[:, j])), 0.0)
    return out[0], out[1]
