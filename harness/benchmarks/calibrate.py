"""`harness bench calibrate --device DEV`: the unit costs of a study's per-image work on one device,
for ``harness plan --estimate`` (``calibrate-cuda.json`` beside the CPU's benchmark files).

On the smallest real scene at hand (:func:`harness.run.calibrate._scene`), wall seconds on DEV, each
the best of ``--repeats`` after a warm-up (CUDA contexts, cuDNN's choices, numba's compile):

* a GL render at half ``--size`` and at ``--size`` px (longest side): the per-pixel term is the
  difference over the pixel difference, the per-splat term what is left at half size (projection,
  sort, packing, upload, draw, read-back). Not 128 px, as ``plan --calibrate`` on the CPU: llvmpipe
  took longer for a 128-px render of bonsai-7k-mini than for a 1024-px one (6.6 s vs 2.1 s here,
  273k one-pixel triangles), which makes that difference meaningless;
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
    parser.add_argument("--device", default="cuda", help="torch device to calibrate (default cuda; cpu to try it)")
    parser.add_argument("--size", type=int, default=1024, help="longest image side (default 1024, the CTC's)")
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats, best kept (default 3)")


def _best(fn, repeats: int) -> float:
    """Least wall seconds of ``repeats`` calls after a warm-up call."""
    from harness.run.calibrate import _cpu

    fn()
    return _cpu(fn, repeats, clock=time.perf_counter)


def _pass_names() -> dict[str, tuple[str, ...]]:
    from harness.metrics.registry import METRICS, expand

    names = expand(FAMILIES)
    return {kind: tuple(n for n in names if METRICS.get(n).cost == kind) for kind in ("lpips", "ssim", "psnr")}


def _metrics(device: str, img: np.ndarray, alpha: np.ndarray, repeats: int) -> tuple[dict, dict]:
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
        seconds = _best(lambda: suite.score_many("v", images, alphas), repeats) / batch
        units[f"{kind}_px"] = seconds / len(names) / (h * w)
        raw[kind] = {"metrics": list(names), "batch": batch, "seconds_per_image": seconds}
        if kind == "lpips":
            ref = _best(lambda: suite.reference("v", img, alpha=alpha), repeats)
            units["lpips_ref_px"] = ref / (h * w)
            raw["lpips_reference_s"] = ref
    return units, raw


def run(args) -> int:
    from harness.benchmarks._common import out_dir, write_result
    from harness.benchmarks._study_device import _machine
    from harness.core.devices import check_device
    from harness.core.errors import InputError
    from harness.run.calibrate import _scene
    from harness.views import rigs

    folder = out_dir(args)
    device = check_device(args.device, "--device")
    if not 128 < args.size <= 4096:
        raise InputError("--size", f"must be in 129..4096, got {args.size}")
    if args.repeats < 1:
        raise InputError("--repeats", f"must be >= 1, got {args.repeats}")
    name, scene = _scene()
    if scene is None:
        raise InputError("scenes", "no real scene here to calibrate on (harness fetch --scenes)")
    from renderers.gl import GLRenderer

    cam = rigs.make_rig("auto", scene, n_train=0, n_test=1, longest_side=args.size).test[0]
    small = cam.resized(args.size // 2)
    gl = GLRenderer(device=device)
    try:
        t_small = _best(lambda: gl.render(scene, small), args.repeats)
        t_big = _best(lambda: gl.render(scene, cam), args.repeats)
        img, alpha = gl.render_with_alpha(scene, cam)
    finally:
        gl.close()
    px_small, px_big = small.width * small.height, cam.width * cam.height
    render_px = max(t_big - t_small, 0.0) / (px_big - px_small)
    units = {"render_px": render_px, "render_splat": max(t_small - render_px * px_small, 0.0) / len(scene)}
    metric_units, raw = _metrics(device, np.asarray(img, np.float32), np.asarray(alpha, np.float32), args.repeats)
    units.update(metric_units)
    payload = {"device": device, "device_name": _machine(), "scene": name, "splats": len(scene),
               "size": [cam.width, cam.height], "units": units,
               "seconds": {"render_half": t_small, "render_full": t_big, **raw}}
    md = _markdown(payload)
    write_result(f"{NAME}-{device.replace(':', '')}", payload, md, out=folder)
    print(md)
    return 0


def _markdown(p: dict) -> str:
    w, h = p["size"]
    s = p["seconds"]
    lines = [f"# harness bench calibrate --device {p['device']} ({p['device_name']})", "",
             f"{p['scene']} ({p['splats']:,} splats), {w}×{h}; wall seconds, best of the repeats after a warm-up.", "",
             "| unit | value (s) |", "|---|---|"]
    lines += [f"| {k} | {v:.3g} |" for k, v in p["units"].items()]
    lines += ["", "| work | batch | s per image |", "|---|---|---|",
              f"| GL render {max(w, h) // 2} px | 1 | {s['render_half']:.4f} |",
              f"| GL render {max(w, h)} px | 1 | {s['render_full']:.4f} |"]
    lines += [f"| {k}: {', '.join(s[k]['metrics'])} | {s[k]['batch']} | {s[k]['seconds_per_image']:.4f} |"
              for k in ("lpips", "ssim", "psnr")]
    lines += [f"| LPIPS reference features | 1 | {s['lpips_reference_s']:.4f} |", "",
              "`harness plan CONFIG --estimate` reads `calibrate-cuda.json` from the benchmark folder for the time "
              "on one GPU" + (" (this file measures the CPU: a check of the benchmark)." if p["device"] == "cpu"
                              else ".")]
    return "\n".join(lines)

