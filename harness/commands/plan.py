"""`harness plan CONFIG [--estimate] [--workers N] [--out FILE.json]`: the work of a cold run, counted.

Without ``--estimate``: the units of work per stage (score tasks, prune selections, reference
renders, measured images, metric passes) and per scene — nothing is rendered, scene files are
read only as far as their headers. With ``--estimate``: × unit costs measured on this machine
(``results/bench/*.json``, or ``--calibrate``) → CPU-hours per stage, projected wall time on N
workers and the nodes an overnight run needs (:mod:`harness.run.estimate`). Scenes whose data is
absent are estimated from the ``--assume-*`` values and marked as assumed; a scene name that is
neither a named dataset nor a file (a typo) is an error with "did you mean". Markdown on stdout;
``--out FILE`` also writes JSON.
"""

from __future__ import annotations

from pathlib import Path

from harness.commands import help_text
from harness.core import jsonout

NAME = "plan"
HELP = "count the work of a cold run of a config; --estimate: CPU-hours, wall time on N workers, nodes"
WORKER_LIST = (1, 2, 8, 32, 128)


def _size(text: str) -> tuple[int, int]:
    import argparse

    try:
        w, h = (int(v) for v in text.lower().split("x"))
        if w > 0 and h > 0:
            return w, h
    except ValueError:
        pass
    raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, e.g. 1920x1080, got {text!r}")


def add_arguments(parser) -> None:
    parser.add_argument("config", help="run config (YAML), e.g. ctc_configs/ctc.yaml")
    parser.add_argument("--estimate", action="store_true", help="cost the counts: CPU-hours, wall time, nodes")
    parser.add_argument("--workers", type=int, default=None, help="workers to project for (default: the config's)")
    parser.add_argument("--efficiency", type=float, default=None,
                        help=help_text("parallel efficiency of the pool (default 0.95 = 95 %: two cold runs of the "
                                       "default study on a 2-core machine used 97 % and 98 % of its cores; a small "
                                       "study's 2 workers ran 1.78x as fast as one)"))
    parser.add_argument("--cores-per-node", type=int, default=16, help="cores of one node (default 16)")
    parser.add_argument("--hours", type=float, default=8.0, help="length of an overnight run (default 8 h)")
    parser.add_argument("--bench", default=None, help="benchmark results folder (default: results/bench)")
    parser.add_argument("--calibrate", action="store_true",
                        help="measure render, metric and scoring unit costs here first (a few seconds)")
    parser.add_argument("--assume-frames", type=int, default=32, help="frames of an absent sequence (default 32)")
    parser.add_argument("--assume-views", type=int, default=None,
                        help="cameras of an absent sequence (default: 21; breakfast 15)")
    parser.add_argument("--assume-splats", type=int, default=1_000_000,
                        help="splats per frame of an absent scene (default 1,000,000)")
    parser.add_argument("--assume-size", type=_size, default=(1920, 1080),
                        help="native size of an absent sequence (default 1920x1080)")
    parser.add_argument("--out", default=None, help="also write the result as JSON to this file")


def _check(args) -> None:
    from harness.core.errors import InputError

    for flag, v, lo in (("--workers", args.workers, 1), ("--cores-per-node", args.cores_per_node, 1),
                        ("--assume-frames", args.assume_frames, 1), ("--assume-views", args.assume_views, 1),
                        ("--assume-splats", args.assume_splats, 1)):
        if v is not None and v < lo:
            raise InputError(flag, f"must be at least {lo}, got {v}")
    if args.efficiency is None:
        from harness.run.estimate import DEFAULT_EFFICIENCY

        args.efficiency = DEFAULT_EFFICIENCY
    if not 0 < args.efficiency <= 1:
        raise InputError("--efficiency", f"must be in (0, 1], got {args.efficiency}")
    if not 0 < args.hours <= 1000:
        raise InputError("--hours", f"must be in (0, 1000], got {args.hours}")


def run(args) -> int:
    from harness.run.config import load_config
    from harness.run.estimate import Assumptions, estimate, scene_info

    _check(args)
    config = load_config(args.config)
    from harness.run.sources import check_sources
    from harness.run.toolkit import Toolkit

    check_sources(config, Toolkit(), Path.cwd(), names_only=True)  # a misspelt scene name: one line, exit 2
    assume = Assumptions(args.assume_frames, args.assume_views, args.assume_splats, tuple(args.assume_size))
    infos = [scene_info(s, config, assume) for s in config.scenes]
    units = None
    if args.estimate:
        from harness.run.view_coverage import look

        units = _units(args)
        look(infos, config, Path.cwd())
    est = estimate(config, infos, units)
    workers = args.workers or config.workers
    doc = to_json(args, config, est, units, assume, workers)
    if units is not None:
        from harness.run.estimate_device import one_gpu

        doc["one_gpu"] = one_gpu(config, infos, _bench(args), units, args.cores_per_node, args.efficiency)
    print(markdown(doc))
    if args.out:
        from harness.io.files import atomic_write_text

        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(out, jsonout.dumps(doc, indent=2, ensure_ascii=False) + "\n")
    return 0


def _bench(args) -> Path:
    from harness.core.paths import results_dir

    return Path(args.bench) if args.bench else results_dir() / "bench"


def _units(args):
    import sys

    from harness.run.unit_costs import from_bench

    units = from_bench(_bench(args))
    if args.calibrate:
        from harness.run.calibrate import calibrate

        units = calibrate(units, log=lambda m: print(m, file=sys.stderr))
    return units


def to_json(args, config, est, units, assume, workers: int) -> dict:
    """Everything :func:`markdown` prints, as one JSON-able dict."""
    from dataclasses import asdict

    from harness.run.unit_costs import COVERAGE_UNITS

    e = args.efficiency
    assumed = [r["scene"] for r in est.scenes if r["status"] == "assumed"]
    doc = {"config": str(args.config), "name": config.name, "metrics": list(config.protocol.metrics),
           "protocols": [p.name for p in config.protocols], "passes_per_image": est.passes,
           "stages": {k: {"units": s.units, **s.detail} for k, s in est.stages.items()},
           "scenes": est.scenes, "assumed": assumed,
           "assumptions": {"frames": assume.frames, "views": assume.views or "21 (breakfast*: 15)",
                           "splats": assume.splats, "size": list(assume.size)},
           "notes": est.notes}
    if units is None:
        return doc
    for k, s in est.stages.items():
        doc["stages"][k].update(core_s=s.core_s, cpu_hours=s.core_s / 3600, unit_s=s.core_s / max(1, s.units),
                                longest_task_s=s.longest_s)
    counts = sorted(set(WORKER_LIST) | {workers})
    by_cpu, fits = est.nodes(args.hours, args.cores_per_node, e)
    big = max(est.scenes, key=lambda r: _px(r["size"]), default=None)
    doc.update(cpu_hours=est.core_s / 3600, efficiency=e, workers=workers,
               workers_from="--workers" if args.workers else "config",
               wall_hours={str(w): est.wall_s(w, e) / 3600 for w in counts},
               overnight={"hours": args.hours, "cores_per_node": args.cores_per_node, "nodes": by_cpu,
                          "nodes_to_fit": fits,
                          "wall_hours": est.wall_s(by_cpu * args.cores_per_node, e) / 3600},
               memory_gib_per_worker=(units.rss_px * _px(big["size"]) / 1024) if big else None,
               units={k: getattr(units, k) for k in ("render_splat", "render_px", *(COVERAGE_UNITS * units.covered),
                                                      "lpips_px", "lpips_ref_px", "ssim_px", "psnr_px", "select_splat",
                                                      "read_splat")},
               seen=asdict(units.seen) if units.covered else None,
               score_units={**units.score_splat, **{k: v[0] for k, v in units.aware.items()}},
               score_shapes={k: v[1] for k, v in units.aware.items()},
               sources=units.sources, unit_notes=units.notes)
    return doc


def _px(size: str) -> int:
    w, h = size.split("/")[0].split("×") if size else (0, 0)
    return int(w) * int(h)


def _n(v) -> str:
    return f"{v:,}" if isinstance(v, int) else f"{v:,.3g}" if v < 100 else f"{v:,.0f}"


_WHAT = {"load": "frames read", "score": "score tasks", "prune": "selections", "render_ref": "reference renders",
         "render+metrics": "images (upper bound)"}


def markdown(doc: dict) -> str:
    est = "cpu_hours" in doc
    n_as = len(doc["assumed"])
    lines = [f"# harness plan {doc['config']}{' --estimate' if est else ''}", "",
             f"{len(doc['scenes'])} scenes ({len(doc['scenes']) - n_as} read, {n_as} assumed); protocols "
             f"{', '.join(doc['protocols'])}; metrics {', '.join(doc['metrics'])} — per image "
             f"{doc['passes_per_image']['lpips']} LPIPS, {doc['passes_per_image']['ssim']} SSIM, "
             f"{doc['passes_per_image']['psnr']} PSNR-like passes.", ""]
    head = "| stage | units |" + (" unit cost (core-s) | CPU-hours | longest task (s) | runs on |" if est else "")
    lines += [head, "|---" * (head.count("|") - 1) + "|"]
    for k, s in doc["stages"].items():
        extra = {"score": f"{s.get('camera_aware_tasks', 0):,} camera-aware, {s.get('training_renders', 0):,} "
                          "training renders",
                 "render+metrics": f"{s.get('view_tasks', 0):,} view tasks; passes: "
                                   + ", ".join(f"{s.get(p + '_passes', 0):,} {p}" for p in ("lpips", "ssim", "psnr"))
                 }.get(k, "")
        units = f"{s['units']:,} {_WHAT[k]}" + (f" ({extra})" if extra else "")
        if est:
            serial = k in ("load", "prune")
            lines.append(f"| {k} | {units} | {_n(s['unit_s'])} | {_n(s['cpu_hours'])} | "
                         f"{'–' if serial else _n(s['longest_task_s'])} | {'driver, serial' if serial else 'pool'} |")
        else:
            lines.append(f"| {k} | {units} |")
    if est:
        lines.append(f"| **total** | | | **{_n(doc['cpu_hours'])}** | | |")
        lines += _wall(doc)
    lines += _scenes(doc)
    if est:
        lines += ["", "## Unit costs (core-seconds)", "", "| unit | value | source |", "|---|---|---|"]
        for k, v in doc["units"].items():
            lines.append(f"| {k} | {v:.3g} | {doc['sources'].get(k, '')} |")
        for k, v in doc["score_units"].items():
            shape = doc["score_shapes"].get(k)
            src = doc["sources"].get(f"aware[{k}]" if shape else f"score[{k}]", "")
            what = {None: "per splat", "rig": "× render of its rig"}.get(shape, "× training render")
            lines.append(f"| score {k} ({what}) | {v:.3g} | {src} |")
        if doc.get("seen"):
            s = doc["seen"]
            lines += ["", f"A view of an assumed scene is taken to see what the calibration's view saw: "
                          f"{100 * s['front']:.0f} % of the splats in front of it, {100 * s['visible']:.0f} % drawn, "
                          f"{s['overdraw']:.0f} footprint pixels per image pixel (harness/run/view_coverage.py)."]
    notes = doc["notes"] + doc.get("unit_notes", [])
    if notes:
        lines += ["", "Notes:", *(f"- {n}" for n in notes)]
    return "\n".join(lines)


def _wall(doc: dict) -> list[str]:
    from harness.run.estimate import POOL_START_S

    w = doc["wall_hours"]
    o = doc["overnight"]
    st = doc["stages"]
    serial = (st["load"]["core_s"] + st["prune"]["core_s"]) / 3600
    fit = (f"{o['nodes_to_fit']} node(s) (the serial stages and longest tasks need more than the CPU-hours alone)"
           if o["nodes_to_fit"] and o["nodes_to_fit"] != o["nodes"] else
           "the same" if o["nodes_to_fit"] else "never: the serial stages and the longest tasks alone exceed it")
    mem = doc.get("memory_gib_per_worker")
    return ["", "## Wall time", "", "| workers | " + " | ".join(w) + " |", "|---" * (len(w) + 1) + "|",
            "| wall (h) | " + " | ".join(_n(v) for v in w.values()) + " |", "",
            f"Workers of one core each at {100 * doc['efficiency']:.0f} % parallel efficiency; the pool stages run one "
            f"after another, each at least as long as its longest task (score: {_n(st['score']['longest_task_s'])} s, "
            f"camera-aware scoring of the largest frame; render+metrics: "
            f"{_n(st['render+metrics']['longest_task_s'])} s, one view task of the largest), plus the pool's start-up "
            f"once (~{POOL_START_S:g} s); one worker runs in-process, at full efficiency; "
            f"load and prune run in the driver, serially ({_n(serial)} h). "
            + (f"Workers asked for (--workers): {doc['workers']}." if doc.get("workers_from") == "--workers"
               else f"Config's workers: {doc['workers']}."),
            "", f"**Overnight ({o['hours']:g} h) on {o['cores_per_node']}-core nodes: {o['nodes']} node(s)** = "
            f"ceil({_n(doc['cpu_hours'])} CPU-h / ({o['hours']:g} h × {o['cores_per_node']} × {doc['efficiency']:g})); "
            f"projected wall on {o['nodes'] * o['cores_per_node']} workers: {_n(o['wall_hours'])} h. "
            f"Fewest nodes whose projected wall fits: {fit}."
            + (f" Memory: ~{mem:.1f} GiB per metrics worker at the largest view size (metrics.json peak RSS, "
               f"scaled by pixels)." if mem else "")] + _one_gpu(doc.get("one_gpu"))


def _one_gpu(g: dict | None) -> list[str]:
    """The projected wall time on one GPU (harness.run.estimate_device), or why there is none."""
    if g is None:
        return []
    if not g["measured"]:
        return ["", f"**On one GPU: not measured.** {g['note']}."]
    per = ", ".join(f"{k} {_n(v / 60)} min" for k, v in g["stages_s"].items())
    return ["", f"**On one GPU ({g['device']}) with {g['cores']} cores: {_n(g['wall_s'] / 60)} min** ({per}); "
                f"units from {g['source']}; {g['note']}."]


def _scenes(doc: dict) -> list[str]:
    est = "cpu_hours" in doc
    lines = ["", "## Scenes", "", "| scene | data | frames | splats/frame | held-out views | size | train views | "
             "pruned sets/frame | images" + (" | CPU-hours |" if est else " |"),
             "|---" * (10 if est else 9) + "|"]
    for r in doc["scenes"]:
        lines.append(f"| {r['scene']} | {r['status']} | {r['frames']} | {r['splats']:,} | {r['views']} | {r['size']} "
                     f"| {r['train_views']} | {r['sets']} | {r['images']:,}"
                     + (f" | {_n(r['core_s'] / 3600)} |" if est else " |"))
    assumed = [r for r in doc["scenes"] if r["status"] == "assumed"]
    if assumed:
        a = doc["assumptions"]
        lines += ["", f"**Assumed** ({len(assumed)} scene(s) whose data is absent here): {a['frames']} frames per "
                  f"sequence, {a['splats']:,} splats per frame, cameras {a['views']} at {a['size'][0]}×{a['size'][1]}; "
                  "override with --assume-frames, --assume-views, --assume-splats, --assume-size.",
                  *(f"- {r['scene']}: {r['note']}" for r in assumed)]
    return lines
