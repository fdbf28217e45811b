"""`harness bench tradeoff`: run time against error for every speed/accuracy knob, in one run.

Knobs and error measures: :mod:`harness.study.tradeoff_knobs`. Output: ``tradeoff.json`` / ``tradeoff.md``
(a table per family, the reference setting marked, Pareto-optimal settings marked) and
``tradeoff_pareto.png`` (CPU seconds vs the family's main error, Pareto front drawn) under
``--out`` (default ``runs/bench``; ``--out results/bench`` updates the committed results).

"Cheapest within tolerance" per family is the fastest (CPU) setting whose error stays inside the
tolerances of nightly tracking (:data:`harness.report.tracking.DEFAULT_TOLERANCES`: |ΔPSNR| ≤ 0.5 dB,
|ΔSSIM| ≤ 0.005, |ΔLPIPS| ≤ 0.005) tightened tenfold for PSNR (0.05 dB) — a default must not eat the
regression budget — and, for pruning knobs, Jaccard of removed sets ≥ 0.9 and Spearman ρ ≥ 0.95.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

NAME = "tradeoff"
HELP = "run time vs error of the speed/accuracy knobs (descriptors, resolution, LPIPS, renderer)"

MAIN_ERROR = {"voxel": "1-jaccard@0.3", "radius_voxels": "1-jaccard@0.3", "max_nn": "1-jaccard@0.3",
              "resolution": "|dPSNR|", "lpips_input": "|dLPIPS|", "lpips_precision": "|dLPIPS|",
              "renderer": "|dPSNR|"}
LIMITS = {"1-jaccard@0.3": 0.10, "1-spearman": 0.05, "|dPSNR|": 0.05, "|dSSIM|": 0.005, "|dLPIPS|": 0.005}


def add_arguments(parser) -> None:
    parser.add_argument("--scene", default="bonsai-7k-mini", help="scene name or path (default bonsai-7k-mini)")
    parser.add_argument("--views", type=int, default=2, help="held-out views for the evaluation knobs")
    parser.add_argument("--repeats", type=int, default=1, help="scoring repeats per pruning setting (median)")
    parser.add_argument("--quick", action="store_true", help="few settings at tiny resolutions (for tests)")


def within(errors: dict) -> bool:
    return all(v <= LIMITS[k] for k, v in errors.items() if k in LIMITS)


def _fmt(v) -> str:
    if v is None:
        return "—"
    return f"{v:.3g}" if isinstance(v, float) else str(v)


def markdown(title: str, rows, flags) -> str:
    lines = [f"# {title}", ""]
    families = list(dict.fromkeys(r.family for r in rows))
    picks = {}
    for fam in families:
        fr = [(r, f) for r, f in zip(rows, flags) if r.family == fam]
        keys = list(dict.fromkeys(k for r, _ in fr for k in r.errors))
        lines += [f"## {fam}", "", "| setting | wall s | CPU s | " + " | ".join(keys) + " | Pareto |",
                  "|---|---|---|" + "---|" * len(keys) + "---|"]
        for r, f in fr:
            name = f"**{r.setting}** (ref)" if r.reference else r.setting
            lines.append(f"| {name} | {r.wall_s:.3f} | {r.cpu_s:.3f} | "
                         + " | ".join(_fmt(r.errors.get(k)) for k in keys) + f" | {'yes' if f else ''} |")
        ok = [r for r, _ in fr if within(r.errors)]
        if ok:
            picks[fam] = min(ok, key=lambda r: r.cpu_s).setting
            lines += ["", f"Cheapest within tolerance: **{picks[fam]}**"]
        lines.append("")
    return "\n".join(lines), picks


def plot(path: Path, rows, flags) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    families = list(dict.fromkeys(r.family for r in rows))
    cols = min(4, len(families))
    nrows = -(-len(families) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 3.4 * nrows), squeeze=False)
    for ax, fam in zip(axes.ravel(), families):
        key = MAIN_ERROR[fam]
        pts = [(r, f) for r, f in zip(rows, flags) if r.family == fam]
        xs = [r.cpu_s for r, _ in pts]
        ys = [r.errors.get(key, 0.0) for r, _ in pts]
        ax.scatter(xs, ys, c=["tab:red" if f else "tab:gray" for _, f in pts], zorder=3)
        front = sorted((x, y) for (x, y, (_, f)) in zip(xs, ys, pts) if f)
        if front:
            ax.step([p[0] for p in front], [p[1] for p in front], where="post", color="tab:red", lw=1.2,
                     label="Pareto front")
        for (r, _), x, y in zip(pts, xs, ys):
            ax.annotate(r.setting + (" (ref)" if r.reference else ""), (x, y), fontsize=7,
                        xytext=(3, 3), textcoords="offset points")
        if max(xs) >= 10 * max(min(xs), 1e-9):  # log axis only when the times span a decade
            ax.set_xscale("log")
            ax.xaxis.set_minor_formatter(NullFormatter())  # minor log labels collide
        ax.set_title(fam)
        ax.set_xlabel("CPU seconds" + (" per scene" if key.startswith("1-") else " per view"))
        ax.set_ylabel(key)
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[len(families):]:
        ax.axis("off")
    fig.tight_layout()
    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(path)


def run(args) -> int:
    import numpy as np

    from harness.core.errors import InputError
    from harness.io.datasets import identify
    from harness.io.scenes import load_scene
    from harness.metrics.lpips_vgg import LpipsVGG
    from harness.report.machine import describe_machine as machine
    from harness.report.machine import time_calibration
    from harness.study.tradeoff_knobs import (
        PRUNE_FAMILIES,
        QUICK_PRUNE,
        Evaluator,
        eval_knobs,
        pareto_front,
        prune_knobs,
    )
    from harness.views.rigs import scene_rig
    from methods.targeting import select_by_ratio

    if args.views < 1 or args.repeats < 1:
        raise InputError("--views/--repeats", "must be at least 1")
    from harness.benchmarks._common import out_dir, tracked_note

    out = out_dir(args)  # created and probed before any work
    t_all = time.perf_counter()
    scene = load_scene(args.scene)
    if args.quick:
        families, sides, lp_sides, r_side = QUICK_PRUNE, [48, 96], [32, 48], 48
    else:
        families, sides, lp_sides, r_side = PRUNE_FAMILIES, [128, 256, 512, 1024], [128, 224, 256, 512], 256
    print(f"tradeoff: {args.scene} ({len(scene):,} splats), {args.views} views")
    rows, default_scores = prune_knobs(scene, families, args.repeats)
    print(f"  pruning knobs: {len(rows)} settings")
    pruned = scene.subset(select_by_ratio(default_scores, 0.3).keep)
    cams = scene_rig(identify(args.scene), scene, n_train=0, n_test=args.views, longest_side=max(sides)).test
    ev = Evaluator(scene, pruned, cams, LpipsVGG(device="cpu"), LpipsVGG(device="cpu", precision="bfloat16"))
    try:
        rows += eval_knobs(ev, sides, lp_sides, r_side)
    finally:
        ev.close()
    flags = []
    for fam in dict.fromkeys(r.family for r in rows):
        fr = [r for r in rows if r.family == fam]
        flags += pareto_front([(r.cpu_s, r.errors.get(MAIN_ERROR[fam], 0.0)) for r in fr])
    title = f"harness bench tradeoff ({args.scene}, {len(scene):,} splats, {args.views} views)"
    md, picks = markdown(title, rows, flags)
    md += (f"\nRenderer family measured at {r_side} px. Times: pruning per scene, evaluation per view. "
           f"Tolerances for 'cheapest within tolerance': {LIMITS}.\n")
    payload = {"benchmark": NAME, "when": time.strftime("%Y-%m-%dT%H:%M:%S"), "machine": machine(),
               "calibration_s": time_calibration(), "scene": str(args.scene), "splats": len(scene),
               "views": args.views, "quick": bool(args.quick), "renderer_side": r_side, "limits": LIMITS,
               "cheapest_within_tolerance": picks, "wall_s": time.perf_counter() - t_all,
               "rows": [{**r.__dict__, "pareto": f,
                         "errors": {k: (v if np.isfinite(v) else None) for k, v in r.errors.items()}}
                        for r, f in zip(rows, flags)]}
    (out / "tradeoff.json").write_text(json.dumps(payload, indent=2, allow_nan=False) + "\n")
    (out / "tradeoff.md").write_text(md)
    plot(out / "tradeoff_pareto.png", rows, flags)
    print(md)
    print(f"wrote {out / 'tradeoff.json'}, {out / 'tradeoff.md'}, {out / 'tradeoff_pareto.png'} "
          f"({payload['wall_s']:.0f} s){tracked_note(out)}")
    return 0
