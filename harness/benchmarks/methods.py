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
3. **Backends** (``--backends``): the significance sums of ``lightgs`` (the rig's training views at
   its 512 px) and ``virtual-rig`` (its own rig, placed once and timed apart) computed by each exact
   CPU backend of :func:`methods.lightgs.significance.significance` — ``sweep`` (the default) and
   ``pairs`` (the pixel-pair compositing it replaced) — one after the other in this process, one
   torch thread: CPU seconds of each, their ratio, and whether the sums are identical (max relative
   difference, Spearman ρ). ``--stem`` names the result files (``methods-<scene>`` for the committed
   per-scene reports under ``results/virtualrig/bench/``).
4. **Descriptor overhead** (``--overhead``; the paper's runtime claim, L474): per scene of ``--scenes``
   (default the five of ``default.yaml``), ``betadesc`` and ``betadesc-nodesc`` (default parameters:
   the paper-literal reading, the faithful no-descriptor ablation) each prune the scene end to end
   (read, score, select, write) in a child process with every thread pool pinned to one, warm-up
   then ``--repeats`` interleaved rounds, process CPU seconds (:mod:`harness.benchmarks._overhead`).
   Writes ``overhead.json`` / ``.md`` (``--out results/bench`` updates the file the ``claims`` table
   reads): per scene the added seconds and the overhead %, each a mean with its t interval over
   the rounds, and a note where our no-descriptor baseline differs from the paper's by more than 5×.
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path

import numpy as np

NAME = "methods"
HELP = "scoring seconds of every registered pruner on bonsai-7k-mini (+ --quality: PSNR of 30 % pruned renders)"
QUALITY_METHODS = ("lightgs", "confsplat", "opacity", "random", "betadesc", "virtual-rig")


OVERHEAD_SCENES = "bonsai-7k,bonsai-7k-mini,luigi,grape-small,playbot"
OVERHEAD_PAIR = ("betadesc", "betadesc-nodesc")


def add_arguments(parser) -> None:
    parser.add_argument("--scene", default="bonsai-7k-mini", help="scene name or path (default bonsai-7k-mini)")
    parser.add_argument("--overhead", action="store_true",
                        help="time betadesc vs betadesc-nodesc end to end on one thread per scene (overhead.*)")
    parser.add_argument("--scenes", default=OVERHEAD_SCENES, help="--overhead: comma-separated scenes")
    parser.add_argument("--repeats", type=int, default=5, help="--overhead: interleaved timings per method")
    parser.add_argument("--methods", default="", help="comma-separated pruners (default: every registered one)")
    parser.add_argument("--quality", action="store_true", help="also render pruned vs unpruned test views")
    parser.add_argument("--ratio", type=float, default=0.3, help="pruning ratio of the quality study and of --overhead")
    parser.add_argument("--test-views", type=int, default=4, help="held-out views rendered (default 4)")
    parser.add_argument("--renderer", choices=("gl", "reference"), default="gl")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--backends", action="store_true",
                        help="also time lightgs's and virtual-rig's significance with the sweep and the pairs backend")
    parser.add_argument("--stem", default=NAME, help="result file name without suffix (default methods)")


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


def _backends(scene, rig, names: list[str]) -> dict:
    """Sweep vs pairs on the same views (module docstring, 3)."""
    from scipy.stats import spearmanr

    from methods.lightgs import LightGSParams
    from methods.lightgs.significance import significance
    from methods.virtualrig import VirtualRigParams, virtual_cameras
    from renderers.pixel_pairs import torch_threads

    jobs = {}
    if "lightgs" in names:
        jobs["lightgs"] = {"cameras": rig.train, "side": LightGSParams().train_longest_side, "rig_cpu_s": 0.0}
    if "virtual-rig" in names:
        c0 = time.process_time()
        cams = virtual_cameras(scene, VirtualRigParams())[1]
        jobs["virtual-rig"] = {"cameras": cams, "side": 0, "rig_cpu_s": time.process_time() - c0}
    out = {}
    for name, job in jobs.items():
        sums, cpu = {}, {}
        for backend in ("sweep", "pairs"):
            with torch_threads(1):
                c0 = time.process_time()
                sums[backend] = significance(scene, job["cameras"], longest_side=job["side"], backend=backend)
                cpu[backend] = time.process_time() - c0
        a, b = sums["sweep"], sums["pairs"]
        out[name] = {"views": len(job["cameras"]), "rig_cpu_s": job["rig_cpu_s"], "sweep_cpu_s": cpu["sweep"],
                     "pairs_cpu_s": cpu["pairs"], "ratio": cpu["pairs"] / max(cpu["sweep"], 1e-9),
                     "identical": bool(np.array_equal(a, b)),
                     "max_rel_diff": float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300)),
                     "spearman": float(spearmanr(a, b)[0]) if len(a) > 1 else 1.0}
        r = out[name]
        print(f"{name}: sweep {r['sweep_cpu_s']:.2f} CPU-s, pairs {r['pairs_cpu_s']:.2f} ({r['ratio']:.1f}x), "
              f"identical {r['identical']}", flush=True)
    return out


def _backends_markdown(backends: dict) -> list[str]:
    lines = ["", "Significance backends on the same views, one torch thread, in this process (CPU seconds; "
             "the virtual rig's placement timed apart):", "",
             "| pruner | views | rig CPU s | sweep CPU s | pairs CPU s | pairs / sweep | identical "
             "| max rel. diff | ρ |",
             "|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {m} | {b['views']} | {b['rig_cpu_s']:.2f} | {b['sweep_cpu_s']:.2f} | {b['pairs_cpu_s']:.2f} | "
              f"{b['ratio']:.1f}× | {'yes' if b['identical'] else 'no'} | {b['max_rel_diff']:.1e} "
              f"| {b['spearman']:.6f} |" for m, b in backends.items()]
    return lines


def _markdown(scene_name: str, n: int, n_train: int, timings: dict, quality: dict | None) -> str:
    lines = [f"# harness bench methods ({scene_name}, {n:,} splats, {n_train} training views)", "",
             "| method | needs | wall s | CPU s | load before |", "|---|---|---|---|---|"]
    lines += [
        f"| {m} | {', '.join(t['needs']) or '-'} | {t['wall_s']:.2f} | {t['cpu_s']:.2f} | {t['load_before']:.1f} |"
        for m, t in timings.items()
    ]
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


def overhead(scenes: list[str], repeats: int, ratio: float = 0.3) -> dict:
    """End-to-end prune seconds of the full method and the no-descriptor variant, one thread (module doc)."""
    import tempfile

    from harness.benchmarks import _overhead as oh

    with tempfile.TemporaryDirectory(prefix="harness-overhead-") as scratch:
        child = oh.run_child(scenes, repeats, ratio, scratch)
    rows = [oh.summarise(r) for r in child["rows"]]
    for r in rows:
        lo, hi = r["overhead_ci"]
        print(f"{r['scene']}: full {np.mean(r['full_cpu']):.3f} s, no-desc {np.mean(r['nodesc_cpu']):.3f} s CPU, "
              f"added {r['added_mean']:+.3f} s, overhead {r['overhead_mean']:+.0f} % [{lo:+.0f}, {hi:+.0f}]",
              flush=True)
    return {"threads": 1, "pools": child["pools"], "repeats": repeats, "ratio": ratio, "methods": list(oh.PAIR),
            "timed": "end to end: read, score, select, write (process CPU seconds, one thread)",
            "paper": oh.PAPER, "note": oh.baseline_note(rows), "scenes": rows,
            "load_average_after": os.getloadavg()}


def _pools(pools: dict) -> str:
    return "; ".join(f"{k}: {', '.join(v) if isinstance(v, list) else v}" for k, v in pools.items())


def _overhead_markdown(payload: dict) -> str:
    lines = ["# Descriptor overhead, end to end on one thread (`harness bench methods --overhead`)", "",
             f"One prune = read, score, select ({100 * payload['ratio']:g} %), write the .ply, timed in a process "
             f"whose thread pools are pinned to one ({_pools(payload['pools'])}); "
             f"process CPU seconds, mean of {payload['repeats']} interleaved rounds after a warm-up; wall seconds "
             "beside them (the machine may be shared: its other jobs show in the wall time, not in the CPU time; "
             f"load average after the run: {payload['load_average_after'][0]:.1f}). "
             "BetaDescPrune and its no-descriptor ablation, default parameters. Added = full − no-desc per round; "
             "overhead = 100·added/no-desc; each a mean [95 % t interval over the rounds]. The paper (L474): "
             "7.29 vs 6.78 s per scene, +0.5 s, ≈ 8 %.", "",
             "| scene | splats | full CPU (s) | no-desc CPU (s) | wall full / no-desc (s) | added (s) | overhead % |",
             "|---|---|---|---|---|---|---|"]
    for r in payload["scenes"]:
        (lo, hi), (alo, ahi) = r["overhead_ci"], r["added_ci"]
        lines.append(
            f"| {r['scene']} | {r['splats']:,} | {np.mean(r['full_cpu']):.3f} | {np.mean(r['nodesc_cpu']):.3f} "
            f"| {np.mean(r['full_wall']):.3f} / {np.mean(r['nodesc_wall']):.3f} "
            f"| {r['added_mean']:+.3f} [{alo:+.3f}, {ahi:+.3f}] | {r['overhead_mean']:+.0f} [{lo:+.0f}, {hi:+.0f}] |"
        )
    stages = ["", "CPU seconds per stage (mean over the rounds), full / no-desc:", "",
              "| scene | read | score | select | write |", "|---|---|---|---|---|"]
    for r in payload["scenes"]:
        f, n = (r["stages_cpu_s"][m] for m in payload["methods"])
        stages.append(f"| {r['scene']} | " + " | ".join(f"{f[s]:.3f} / {n[s]:.3f}" for s in
                                                         ("read", "score", "select", "write")) + " |")
    note = ["", f"Note: {payload['note']}."] if payload.get("note") else []
    return "\n".join(lines + stages + note)


def run(args) -> int:
    from harness.benchmarks._common import out_dir, write_result
    from harness.core.errors import InputError
    from harness.io.datasets import identify
    from harness.io.scenes import load_scene
    from harness.views.rigs import scene_rig
    from methods import list_pruners

    if not args.stem or args.stem != Path(args.stem).name or args.stem.startswith("."):
        raise InputError("--stem", f"a file name without folders, got {args.stem!r}")
    folder = out_dir(args)  # created and probed before any work
    if args.overhead:
        scenes = [s.strip() for s in args.scenes.split(",") if s.strip()]
        if not 0.0 < args.ratio < 1.0:
            raise InputError("--ratio", f"must be in (0, 1), got {args.ratio}")
        if args.repeats < 2:
            raise InputError("--repeats", f"needs at least 2 timings for an interval, got {args.repeats}")
        payload = overhead(scenes, args.repeats, args.ratio)
        md = _overhead_markdown(payload)
        path = write_result("overhead", payload, md, out=folder)
        print(md)
        print(f"\nwritten {path}")
        return 0
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
    backends = _backends(scene, rig, names) if args.backends else None
    payload = {"scene": args.scene, "splats": len(scene), "rig": rig.rig, "train_views": len(rig.train),
               "train_resolution": [rig.train[0].width, rig.train[0].height], "scoring": timings,
               "quality": quality, "backends": backends, "load_average_after": os.getloadavg()}
    md = _markdown(args.scene, len(scene), len(rig.train), timings, quality)
    md += "\n" + "\n".join(_backends_markdown(backends)) if backends else ""
    path = write_result(args.stem, payload, md, out=folder)
    print(md)
    print(f"\nwritten {path}")
    return 0
