"""`harness bench reading select|confirm|directions`: the pre-registered selection of BetaDescPrune's
default reading (round one; rule: ``ctc_configs/reading.yaml``, verbatim), its confirmation on the
other scenes, and which way every reading of ℓ, s, u points.

    harness bench reading select     [--round 1|2] [--config CONFIG] [--workers 2]
    harness bench reading confirm    [--round 1|2] [--config CONFIG] [--workers 2] [--run]
    harness bench reading directions [--scenes luigi,grape-small,bonsai-7k-mini]

Round one: ``ctc_configs/reading.yaml`` / ``reading_confirm.yaml`` (percentile bootstrap, its rule);
round two: ``ctc_configs/reading2.yaml`` / ``reading2_confirm.yaml`` (t interval; also searches
``betadesc-nodesc``'s definition). Reports: ``results/reading/selection[2].md|json``,
``confirmation[2].md``.

``select`` runs the config (``harness run``; cached stages are reused) unless its results exist,
then walks the axes in order (:mod:`harness.report.reading_search`). When an axis needs readings the
results do not hold (after an adoption), it writes a stage config next to the run
(``<output>/stage-<k>-<axis>.yaml``: the same protocol and scenes, ``random`` and the needed readings)
and runs it. It writes ``results/reading/selection.md`` and ``selection.json`` and prints the
selected reading. ``confirm`` runs the confirmation config and writes ``results/reading/confirmation.md``.
``directions`` measures, render-free, the Spearman ρ of every reading of ℓ, s, u with neighbourhood
homogeneity on real scenes (:mod:`methods.betadesc.directions`) and writes
``results/reading/directions.md`` / ``.json``.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
import yaml

from harness.core.paths import REPO_ROOT as REPO
from harness.report import reading_search as rs
from harness.report.results import read_results

NAME = "reading"
HELP = "pre-registered selection (and confirmation) of BetaDescPrune's default reading; results/reading/"


def harness_run(config: Path, workers: int) -> float:
    t0 = time.perf_counter()
    cmd = [sys.executable, "-m", "harness", "run", str(config), "--workers", str(workers)]
    print("$", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True, cwd=REPO)
    return time.perf_counter() - t0


def load_all(output: Path) -> pd.DataFrame:
    frames = [read_results(p.parent) for p in sorted(output.glob("**/results.parquet"))]
    df = pd.concat(frames, ignore_index=True)
    return df.drop_duplicates(["scene", "method", "params", "ratio", "view"], keep="first")


@dataclass(frozen=True)
class Round:
    """One pre-registered selection round: its configs, interval, searched methods and report files."""

    number: int
    config: str
    confirm: str
    searched: tuple[str, ...]
    prefix: str  # variant-name prefix of the start in stage configs
    sides: tuple[tuple[str, dict], ...]  # confirmation: (column, side) vs random
    gains: tuple[tuple[str, dict, dict], ...] = ()  # confirmation: (column, candidate, reference)

    @property
    def interval(self) -> str:
        return rs.INTERVAL[self.number]

    @property
    def suffix(self) -> str:
        return "" if self.number == 1 else str(self.number)


ROUNDS = {
    1: Round(1, "reading.yaml", "reading_confirm.yaml", (rs.METHOD,), "lit", (
        ("betadesc (selected default)", {"method": "betadesc", "variant": "default"}),
        ("betadesc-nodesc (same reading)", {"method": "betadesc-nodesc", "variant": "default"}),
        ("betadesc paper-literal", {"method": "betadesc", "variant": "lit"}),
        ("betadesc v1", {"method": "betadesc", "variant": "v1"}),
        ("opacity", {"method": "opacity", "variant": "default"}))),
    2: Round(2, "reading2.yaml", "reading2_confirm.yaml", rs.SEARCHED, "r1", (
        ("betadesc (round-two default)", {"method": "betadesc", "variant": "default"}),
        ("betadesc (round-one default)", {"method": "betadesc", "variant": "r1"}),
        ("paper-literal", {"method": "betadesc", "variant": "lit"}),
        ("paper-direction", {"method": "betadesc", "variant": "pdir"}),
        ("opacity", {"method": "opacity", "variant": "default"}),
        ("nodesc (default)", {"method": "betadesc-nodesc", "variant": "default"}),
        ("nodesc splat-params", {"method": "betadesc-nodesc", "variant": "splat-params"}),
        ("nodesc param-stats", {"method": "betadesc-nodesc", "variant": "param-stats"})), (
        ("round two − round one", {"method": "betadesc", "variant": "default"}, {"method": "betadesc", "variant": "r1"}),
        ("descriptor gain: betadesc − nodesc (defaults)", {"method": "betadesc", "variant": "default"},
         {"method": "betadesc-nodesc", "variant": "default"}),
        ("Beta gain without descriptors: nodesc − nodesc-nobeta", {"method": "betadesc-nodesc", "variant": "default"},
         {"method": "betadesc-nodesc-nobeta", "variant": "default"}))),
}


def select(args) -> int:
    from harness.benchmarks._common import out_dir, tracked_note

    out = out_dir(args, "reading")  # created and probed before any work
    rnd = ROUNDS[args.round]
    config = Path(args.config)
    raw = yaml.safe_load(config.read_text())
    output = REPO / raw["output"]
    space = rs.search_space(raw, interval=rnd.interval, searched=rnd.searched)
    times = {}
    if not (output / "results.parquet").exists():
        times[str(config)] = harness_run(config, args.workers)
    df = load_all(output)
    incumbents = {m: rs.resolved(p, m) for m, p in space.starts.items()}
    steps = []
    for k, axis in enumerate(space.axes, 1):
        m = axis.method
        wanted = [rs.with_value(incumbents[m], axis, v) for v in axis.values]
        need = rs.missing(df, space, wanted, m)
        if need:
            stage = {k2: v for k2, v in raw.items() if k2 not in ("methods", "output", "name")}
            stage["name"] = f"{raw['name']}-stage-{k}-{axis.name}"
            stage["output"] = f"{raw['output']}/stage-{k}-{axis.name}"
            stage["methods"] = ["random"] + [{"name": m, "variant": rs.label(space, p, m, rnd.prefix),
                                              "params": rs.overrides(space, p, m)} for p in need]
            path = output / f"stage-{k}-{axis.name}.yaml"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(f"# generated by `harness bench reading select` from {config} (axis {k}: {axis.name})\n"
                            + yaml.safe_dump(stage, sort_keys=False))
            times[str(path)] = harness_run(path, args.workers)
            df = load_all(output)
        step = rs.evaluate_axis(df, space, axis, incumbents[m])
        steps.append(step)
        print(f"axis {k} {axis.name}: candidate {step.candidate} "
              + ", ".join(f"{s} {p.text()} hw {p.half_width:.2f}" for s, p in step.delta.items())
              + (" -> ADOPTED" if step.adopted else f" -> kept {step.current}"), flush=True)
        if step.adopted:
            incumbents[m] = rs.with_value(incumbents[m], axis, step.candidate)
    md = rs.selection_markdown(space, steps, incumbents)
    chosen = {m: {p: incumbents[m][p] for a in space.axes if a.method == m for p in a.swept} for m in incumbents}
    (out / f"selection{rnd.suffix}.md").write_text(md)
    (out / f"selection{rnd.suffix}.json").write_text(json.dumps({
        "config": str(config), "interval": rnd.interval,
        "selected": chosen if rnd.number > 1 else chosen[rs.METHOD],
        "steps": [{"axis": s.axis, "method": s.method, "incumbent": s.current, "candidate": s.candidate,
                   "adopted": s.adopted,
                   "d": [{"value": v, "scene": sc, **p.to_dict()} for (v, sc), p in s.d.items()],
                   "delta": {sc: p.to_dict() for sc, p in s.delta.items()}} for s in steps],
        "run_seconds": times}, indent=2, default=str) + "\n")
    print(md)
    print("selected:", json.dumps(chosen))
    print(f"wrote {out / f'selection{rnd.suffix}.md'} and .json{tracked_note(out)}")
    return 0


def confirm(args) -> int:
    from harness.benchmarks._common import out_dir, tracked_note

    out = out_dir(args, "reading")  # created and probed before any work
    rnd = ROUNDS[args.round]
    config = Path(args.config)
    raw = yaml.safe_load(config.read_text())
    output = REPO / raw["output"]
    seconds = None
    if args.run or not (output / "results.parquet").exists():
        seconds = harness_run(config, args.workers)
    df = read_results(output)
    scenes = [s["name"] if isinstance(s, dict) else s for s in raw["scenes"]]
    ratios = list(raw["ratios"])
    name = "bootstrap CI" if rnd.interval == "bootstrap" else "Student-t interval"
    md = (f"D = mean paired per-view PSNR difference vs random (dB) [95 % {name}] (views used/excluded)\n\n"
          + rs.confirmation_markdown(df, scenes, ratios, list(rnd.sides), {"method": "random"}, rnd.interval))
    for title, cand, ref in rnd.gains:
        md += (f"\n{title}: mean paired per-view PSNR difference (dB) [95 % {name}] (views used/excluded)\n\n"
               + rs.confirmation_markdown(df, scenes, ratios, [(title, cand)], ref, rnd.interval))
    (out / f"confirmation{rnd.suffix}.md").write_text(md)
    print(md)
    print(f"wrote {out / f'confirmation{rnd.suffix}.md'}{tracked_note(out)}")
    if seconds is not None:
        print(f"run time {seconds:.0f} s")
    return 0


DIRECTION_SCENES = "luigi,grape-small,bonsai-7k-mini,playbot,bonsai-7k"


def directions(args) -> int:
    from harness.benchmarks._common import out_dir, tracked_note

    out = out_dir(args, "reading")  # created and probed before any work
    from harness.io.scenes import load_scene
    from methods.betadesc import directions as dirs

    scenes = [s.strip() for s in args.scenes.split(",") if s.strip()]
    rows = []
    for name in scenes:
        t0 = time.perf_counter()
        found = dirs.directions(load_scene(name))
        rows += [{"scene": name, **d.__dict__} for d in found]
        print(f"{name}: {time.perf_counter() - t0:.1f} s", flush=True)
    (out / "directions.json").write_text(json.dumps(rows, indent=2) + "\n")
    md = directions_markdown(rows, scenes)
    (out / "directions.md").write_text(md)
    print(md)
    print(f"wrote {out / 'directions.md'} and .json{tracked_note(out)}")
    return 0


def directions_markdown(rows: list[dict], scenes: list[str]) -> str:
    from methods.betadesc.directions import PAPER_DIRECTION

    want = {"ell": "ρ(ℓ, H_geo) > 0", "s": "ρ(s, H_app) > 0", "u": "ρ(u, H_geo) < 0"}
    lines = ["# Which way each reading of ℓ, s, u points (`harness bench reading directions`)", "",
             "Spearman ρ over the voxels (voxel 1 % of the diagonal, radius 5 voxels, max_nn 100, minmax "
             "normalisation) between each statistic as the pipeline computes it and neighbourhood "
             "homogeneity: H_geo = −surface variation of the voxel points of N(j), C = normal coherence "
             "(a check on H_geo), H_app = −colour variance of the splats of N(j) "
             "(`methods/betadesc/directions.py`). The paper's direction: " + "; ".join(
                 f"{k} {v}" for k, v in want.items()) + ". Cell: ρ against the matching homogeneity "
             "(C in brackets for ℓ and u); **P** = preserves the paper's direction, R = reverses it.", "",
             "| statistic | reading | " + " | ".join(scenes) + " |", "|---|---|" + "---|" * len(scenes)]
    by = {(r["scene"], r["statistic"], r["reading"]): r for r in rows}
    for stat, reading in dict.fromkeys((r["statistic"], r["reading"]) for r in rows):
        cells = []
        for sc in scenes:
            r = by[(sc, stat, reading)]
            rho = r["rho_geo"] if PAPER_DIRECTION[stat][0] == "geo" else r["rho_app"]
            extra = f" (C {r['rho_coherence']:+.2f})" if PAPER_DIRECTION[stat][0] == "geo" else ""
            cells.append(f"{rho:+.2f}{extra} {'**P**' if r['preserves'] else 'R'}")
        lines.append(f"| {stat} | `{reading}` | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def add_arguments(parser) -> None:
    parser.add_argument("stage", choices=("select", "confirm", "directions"),
                        help="select the reading, confirm it, or measure the readings' directions")
    parser.add_argument("--scenes", default=DIRECTION_SCENES, help="directions: comma-separated scenes")
    parser.add_argument("--config", default=None, help="the pre-registered config (default: the round's, "
                        "ctc_configs/reading[2].yaml for select, reading[2]_confirm.yaml for confirm)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--round", type=int, choices=sorted(ROUNDS), default=1,
                        help="selection round (1: ctc_configs/reading.yaml, 2: reading2.yaml)")
    parser.add_argument("--run", action="store_true", help="confirm: run the config even if results exist")


def run(args) -> int:
    if args.stage == "directions":
        return directions(args)
    rnd = ROUNDS[args.round]
    args.config = args.config or str(REPO / "ctc_configs" / (rnd.config if args.stage == "select" else rnd.confirm))
    return select(args) if args.stage == "select" else confirm(args)
