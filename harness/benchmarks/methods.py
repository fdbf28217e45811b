"""`harness bench methods`: scoring seconds of every registered pruner, and a first quality look.

1. **Scoring time**: every registered pruner (or ``--methods``) scores ``--scene`` (default
   bonsai-7k-mini) once; camera-aware pruners get the training views of the scene's default rig
   (:func:`harness.views.rigs.scene_rig`, 48 training views at 1024 px; each pruner resizes them to its own
   ``longest_side``). Wall and process CPU seconds per method, with the load average, since the
   machine is shared.
2. **Quality** (``--quality``): at ``--ratio`` (default 30 %) for lightgs, confsplat, opacity, random
   and betadesc (those registered and scored), PSNR of the pruned render against the unpruned render
   on the first ``--test-views`` held-out (test) views of the same rig, with the GL renderer (the
   reference rasterizer if GL cannot start).
"""

from __future__ import annotations

import logging
import os
import time

import numpy as np

NAME = "methods"
HELP = "scoring seconds of every registered pruner on bonsai-7k-mini (+ --quality: PSNR of 30 % pruned renders)"
QUALITY_METHODS = ("lightgs", "confsplat", "opacity", "random", "betadesc", "virtual-rig")


def add_arguments(parser) -> None:
    parser.add_argument("--scene", default="bonsai-7k-mini", help="scene name or path (default bonsai-7k-mini)")
    parser.add_argument("--methods", default="", help="comma-separated pruners (default: every registered one)")
    parser.add_argument("--quality", action="store_true", help="also render pruned vs unpruned test views")
    parser.add_argument("--ratio", type=float, default=0.3, help="pruning ratio of the quality study")
    parser.add_argument("--test-views", type=int, default=4, help="held-out views rendered (default 4)")
    parser.add_argument("--renderer", choices=("gl", "reference"), default="gl")
    parser.add_argument("--seed", type=int, default=0)


def _score_all(scene, rig, names: list[str], seed: int) -> tuple[dict, dict]:
    from methods import PruneContext, get_pruner

    timings, scores = {}, {}
    for name in names:
        spec = get_pruner(name)
        ctx = PruneContext(seed=seed, cameras=rig.train if "cameras" in spec.needs else None)
        load = os.getloadavg()[0]
        t0, c0 = time.perf_counter(), time.process_time()
        scores[name] = spec.score(scene, ctx)
        timings[name] = {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
                         "needs": sorted(spec.needs), "params": spec.parse_params().to_dict(), "load_before": load}
        print(f"{name}: {timings[name]['wall_s']:.2f} s wall, {timings[name]['cpu_s']:.2f} s CPU", flush=True)
    return timings, scores


def _open_renderer(name: str, scene, camera):
    """(renderer, name actually used); GL falls back to the reference rasterizer when it cannot start."""
    from renderers import get_renderer

    if name == "gl":
        try:
            r = get_renderer("gl")
            r.render(scene.subset(np.arange(min(len(scene), 8))), camera)
            return r, "gl"
        except (RuntimeError, ImportError, OSError) as err:  # GLUnavailable is a RuntimeError
            print(f"GL renderer unavailable ({type(err).__name__}: {err}); using the reference rasterizer")
    return get_renderer("reference"), "reference"


def _quality(scene, rig, scores: dict, ratio: float, n_views: int, renderer_name: str) -> dict:
    from harness.metrics.psnr import mse, psnr_from_mse
    from methods import select_by_ratio

    views = rig.test[:n_views]
    renderer, used = _open_renderer(renderer_name, scene, views[0])
    names = [m for m in QUALITY_METHODS if m in scores]
    pruned = {m: scene.subset(select_by_ratio(scores[m], ratio).keep) for m in names}
    psnr = {m: [] for m in names}
    try:
        for cam in views:
            ref = renderer.render(scene, cam)
            for m in names:
                psnr[m].append(psnr_from_mse(mse(ref, renderer.render(pruned[m], cam))))
            print(f"{cam.name}: " + ", ".join(f"{m} {psnr[m][-1]:.2f}" for m in names), flush=True)
    finally:
        renderer.close()
    return {"ratio": ratio, "renderer": used, "views": [c.name for c in views],
            "resolution": [views[0].width, views[0].height], "kept": {m: len(pruned[m]) for m in names},
            "psnr": psnr, "mean_psnr": {m: float(np.mean(v)) for m, v in psnr.items()}}


def _markdown(scene_name: str, n: int, n_train: int, timings: dict, quality: dict | None) -> str:
    lines = [f"# harness bench methods ({scene_name}, {n:,} splats, {n_train} training views)", "",
             "| method | needs | wall s | CPU s | load before |", "|---|---|---|---|---|"]
    lines += [f"| {m} | {', '.join(t['needs']) or '-'} | {t['wall_s']:.2f} | {t['cpu_s']:.2f} | {t['load_before']:.1f} |"
              for m, t in timings.items()]
    if quality:
        w, h = quality["resolution"]
        title = (f"PSNR (dB) of the {quality['ratio']:.0%}-pruned render vs the unpruned render, "
                 f"{quality['renderer']} renderer, {w}×{h}, held-out views:")
        lines += ["", title, "",
                  "| method | kept | " + " | ".join(quality["views"]) + " | mean |",
                  "|---|---|" + "---|" * (len(quality["views"]) + 1)]
        for m, vals in quality["psnr"].items():
            lines.append(f"| {m} | {quality['kept'][m]:,} | " + " | ".join(f"{v:.2f}" for v in vals)
                         + f" | **{quality['mean_psnr'][m]:.2f}** |")
    return "\n".join(lines)


def run(args) -> int:
    from harness.benchmarks._common import write_result
    from harness.core.errors import InputError
    from harness.io.datasets import identify
    from harness.io.scenes import load_scene
    from harness.views.rigs import scene_rig
    from methods import list_pruners

    logging.getLogger("methods").setLevel(logging.INFO)  # confsplat reports its iterations
    logging.basicConfig(format="%(name)s: %(message)s")
    scene = load_scene(args.scene)
    known = [s.name for s in list_pruners()]
    names = [m.strip() for m in args.methods.split(",") if m.strip()] or known
    unknown = sorted(set(names) - set(known))
    if unknown:
        raise InputError("--methods", f"unknown pruner(s) {', '.join(unknown)}; known: {', '.join(known)}")
    if not 0.0 <= args.ratio < 1.0:
        raise InputError("--ratio", f"must be in [0, 1), got {args.ratio}")
    rig = scene_rig(identify(args.scene), scene, seed=args.seed)
    timings, scores = _score_all(scene, rig, names, args.seed)
    quality = _quality(scene, rig, scores, args.ratio, max(1, args.test_views), args.renderer) if args.quality else None
    payload = {"scene": args.scene, "splats": len(scene), "rig": rig.rig, "train_views": len(rig.train),
               "train_resolution": [rig.train[0].width, rig.train[0].height], "scoring": timings,
               "quality": quality, "load_average_after": os.getloadavg()}
    path = write_result(NAME, payload, _markdown(args.scene, len(scene), len(rig.train), timings, quality))
    print(_markdown(args.scene, len(scene), len(rig.train), timings, quality))
    print(f"\nwritten {path}")
    return 0
