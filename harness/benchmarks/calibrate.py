"""`harness bench calibrate --device DEV`: the unit costs of a study's per-image work on one device,
for ``harness plan --estimate`` (``calibrate-cuda.json`` / ``calibrate-cpu.json`` beside the other
benchmark files); ``--check RUN_DIR`` compares the estimate with a finished run instead
(:mod:`harness.run.estimate_check`).

On the smallest real scene at hand (:func:`harness.run.calibrate._scene`), each the best of
``--repeats`` after a warm-up (CUDA contexts, cuDNN's choices, numba's compile) — on a GPU wall
seconds of the device, on the CPU CPU seconds of this process with one thread (torch, OpenMP,
llvmpipe), as a study's one-core workers run:

* the view packed (projection, SH, sort, packing), and packed again 16× zoomed in (as many splats
  in front of the camera, few visible): ``front_splat`` and ``visible_splat`` per splat in front
  and per splat visible (:mod:`harness.run.view_coverage` counts both on the view); ``pack_splat``
  is the packing over all splats;
* the packed view drawn with no splat (``image_px``: clearing and reading back), at ``--size`` and
  at twice it (as many splats, more footprint pixels): ``draw_splat`` per visible splat and
  ``fragment_px`` per footprint pixel, the two equations solved (a unit is never negative). Not
  at half the size: llvmpipe draws the one-pixel splats of a small image at a cost of their own
  (6.6 s for a 128-px render of bonsai-7k-mini against 2.1 s at 1024 px here, 273k one-pixel
  triangles). ``render_px`` (the draw's growth over the pixels it gained) and ``render_splat``
  (``pack_splat`` + the rest of the draw per splat) are the plain model's, for a view of unknown
  coverage where the coverage units are absent (a GPU calibration without them);
* the metric suite a study on DEV makes (:class:`harness.metrics.suite.MetricSuite`: the torch
  forms, batched, on CUDA; the CPU forms image by image on the CPU) scoring one batch of pruned
  renders at ``--size``, per pass kind of :data:`harness.metrics.registry.PASS_KINDS`: LPIPS (and a
  reference's features), the SSIM-like metrics and the PSNR-like ones of the ``3dgs`` and ``mpeg``
  families, each kind's seconds per image divided by its metrics and the pixels — the units
  :mod:`harness.run.estimate` multiplies by its pass counts.

On a GPU the units are seconds of one device (its work is serial; :mod:`harness.run.estimate_device`);
on the CPU, seconds of this process with its threads (a check of the benchmark, not the CPU's
units, which come from the other benchmarks).
"""

from __future__ import annotations

import time

import numpy as np

NAME = "calibrate"
HELP = "unit costs of the per-image work (render, LPIPS, SSIM- and PSNR-like passes) on a device, for plan --estimate"
FAMILIES = ("3dgs", "mpeg")


def add_arguments(parser) -> None:
    parser.add_argument("--device", default="cuda", help="torch device to calibrate (default cuda; cpu: the units "
                                                         "of plan --estimate on this machine, calibrate-cpu.json)")
    parser.add_argument("--size", type=int, default=None,
                        help="longest image side (default: 1024, the CTC's, on a GPU; 256, the default study's, "
                             "on the CPU)")
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats, best kept (default 3)")
    parser.add_argument("--check", metavar="RUN_DIR", default=None,
                        help="compare `plan --estimate` of a finished run's config with what the run measured "
                             "(CPU seconds, wall, per stage and per view protocol; within 20 %% or not)")
    parser.add_argument("--efficiency", type=float, default=None,
                        help="parallel efficiency for --check's wall time (default 0.95, as plan's)")
    parser.add_argument("--bench", default=None, help="--check: benchmark folder of the units (default results/bench)")


#: the clock of the measurements: wall seconds of a GPU, CPU seconds of this process on the CPU
_CLOCK = {"cpu": time.process_time}


def _best(fn, repeats: int, clock=time.perf_counter) -> float:
    """Least ``clock`` seconds of ``repeats`` calls after a warm-up call."""
    from harness.run.calibrate import _best as best

    return best(fn, repeats, clock)


def _pass_names() -> dict[str, tuple[str, ...]]:
    from harness.metrics.registry import METRICS, expand

    names = expand(FAMILIES)
    return {kind: tuple(n for n in names if METRICS.get(n).cost == kind) for kind in ("lpips", "ssim", "psnr")}


def _metrics(device: str, img: np.ndarray, alpha: np.ndarray, repeats: int, clock) -> tuple[dict, dict]:
    from harness.metrics.suite import MetricSuite

    rng = np.random.default_rng(0)
    h, w = img.shape[:2]
    units, raw = {}, {}
    for kind, names in _pass_names().items():
        suite = MetricSuite(names=names, device=device, max_in_memory=1)
        batch = suite.batch_size(h, w)
        images = [np.clip(img + rng.normal(0, 0.01, img.shape), 0, 1).astype(np.float32) for _ in range(batch)]
        alphas = [alpha] * batch if suite.wants_alpha else None
        suite.reference("v", img, alpha=alpha)
        seconds = _best(lambda: suite.score_many("v", images, alphas), repeats, clock) / batch
        units[f"{kind}_px"] = seconds / len(names) / (h * w)
        raw[kind] = {"metrics": list(names), "batch": batch, "seconds_per_image": seconds}
        if kind == "lpips":
            ref = _best(lambda: suite.reference("v", img, alpha=alpha), repeats, clock)
            units["lpips_ref_px"] = ref / (h * w)
            raw["lpips_reference_s"] = ref
    return units, raw


def run(args) -> int:
    from harness.benchmarks._common import out_dir, write_result
    from harness.core.devices import check_device
    from harness.core.errors import InputError

    folder = out_dir(args)
    if args.check is not None:
        from harness.run.estimate_check import check_run

        payload, md = check_run(args.check, bench=args.bench, efficiency=args.efficiency)
        write_result(f"{NAME}-check-{payload['name']}", payload, md, out=folder)
        print(md)
        return 0
    device = check_device(args.device, "--device")
    size = args.size if args.size is not None else (256 if device == "cpu" else 1024)
    if not 128 < size <= 4096:
        raise InputError("--size", f"must be in 129..4096, got {size}")
    if args.repeats < 1:
        raise InputError("--repeats", f"must be >= 1, got {args.repeats}")
    if device == "cpu":
        from harness.run.calibrate import one_thread

        with one_thread():
            payload = _calibrate(device, size, args.repeats)
    else:
        payload = _calibrate(device, size, args.repeats)
    md = _markdown(payload)
    write_result(f"{NAME}-{device.replace(':', '')}", payload, md, out=folder)
    print(md)
    return 0


def _calibrate(device: str, size: int, repeats: int) -> dict:
    from harness.benchmarks._study_device import _machine
    from harness.core.errors import InputError
    from harness.run.calibrate import _scene, render_units
    from harness.views import rigs

    name, scene = _scene()
    if scene is None:
        raise InputError("scenes", "no real scene here to calibrate on (harness fetch --scenes)")
    from renderers.gl import GLRenderer

    clock = _CLOCK.get(device, time.perf_counter)
    cam = rigs.make_rig("auto", scene, n_train=0, n_test=1, longest_side=size).test[0]
    gl = GLRenderer(device=device)
    try:
        units, seconds, seen = render_units(gl, scene, cam, repeats, clock)
        img, alpha = gl.render_with_alpha(scene, cam)
    finally:
        gl.close()
    metric_units, raw = _metrics(device, np.asarray(img, np.float32), np.asarray(alpha, np.float32), repeats, clock)
    units.update(metric_units)
    return {"device": device, "device_name": _machine() if device != "cpu" else "CPU, one thread",
            "clock": "CPU seconds" if device == "cpu" else "wall seconds", "scene": name, "splats": len(scene),
            "size": [cam.width, cam.height], "units": units, "seen": seen, "seconds": {**seconds, **raw}}


def _markdown(p: dict) -> str:
    w, h = p["size"]
    s = p["seconds"]
    lines = [f"# harness bench calibrate --device {p['device']} ({p['device_name']})", "",
             f"{p['scene']} ({p['splats']:,} splats), {w}×{h}; {p.get('clock', 'wall seconds')}, best of the repeats "
             "after a warm-up. The view sees "
             f"{100 * p['seen']['front']:.0f} % of the splats in front of it, draws {100 * p['seen']['visible']:.0f} % "
             f"of them, {p['seen']['overdraw']:.0f} footprint pixels per image pixel (harness/run/view_coverage.py).",
             "", "| unit | value (s) |", "|---|---|"]
    lines += [f"| {k} | {v:.3g} |" for k, v in p["units"].items()]
    lines += ["", "| work | batch | s per image |", "|---|---|---|",
              f"| GL pack (projection, sort) | 1 | {s['pack']:.4f} |",
              f"| GL pack, 16× zoomed (few splats visible) | 1 | {s['pack_zoomed']:.4f} |",
              f"| GL draw of no splat {max(w, h)} px | 1 | {s['draw_empty']:.4f} |",
              f"| GL draw {max(w, h)} px | 1 | {s['draw_full']:.4f} |",
              f"| GL draw {2 * max(w, h)} px | 1 | {s['draw_double']:.4f} |"]
    lines += [f"| {k}: {', '.join(s[k]['metrics'])} | {s[k]['batch']} | {s[k]['seconds_per_image']:.4f} |"
              for k in ("lpips", "ssim", "psnr")]
    lines += [f"| LPIPS reference features | 1 | {s['lpips_reference_s']:.4f} |", "",
              "`harness plan CONFIG --estimate` reads `calibrate-cpu.json` from the benchmark folder for its CPU "
              "units (they replace the other benchmarks' render and metric units) and `calibrate-cuda.json` for the "
              "time on one GPU."]
    return "\n".join(lines)

