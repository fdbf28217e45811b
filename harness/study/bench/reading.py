"""`harness bench reading select|confirm|directions`: the pre-registered selection of BetaDescPrune's
default reading (round one; rule: ``ctc_configs/study/reading.yaml``, verbatim), its confirmation on the
other scenes, and which way every reading of ℓ, s, u points.

    harness bench reading select     [--round 1|2] [--config CONFIG] [--workers 2]
    harness bench reading confirm    [--round 1|2] [--config CONFIG] [--workers 2] [--run]
    harness bench reading directions [--scenes luigi,grape-small,bonsai-7k-mini]

Round one: ``ctc_configs/study/reading.yaml`` / ``reading_confirm.yaml`` (percentile bootstrap, its rule);
round two: ``ctc_configs/study/reading2.yaml`` / ``reading2_confirm.yaml`` (t interval; also searches
``betadesc-nodesc``'s definition). Reports: ``results/reading/selection[2].md|json``,
``confirmation[2].md``.

``select`` runs the config (``harness run``; cached stages are reused) unless its results exist,
then walks the axes in order (:mod:`harness.study.reading_search`, driven by
:mod:`harness.study.selection`). When an axis needs readings the results do not hold (after an
adoption), it writes a stage config next to the run (``<output>/stage-<k>-<axis>.yaml``: the same
protocol and scenes, ``random`` and the needed readings) and runs it. It writes
``selection[2].md`` and ``.json`` and prints the selected reading. ``confirm`` runs the confirmation
config and writes ``confirmation[2].md``. Both write into ``--out`` (default ``runs/bench/reading``;
``--out results/reading`` updates the committed reports).
``directions`` measures, render-free, the Spearman ρ of every reading of ℓ, s, u with neighbourhood
homogeneity on real scenes (:mod:`harness.study.directions`) and writes
``results/reading/directions.md`` / ``.json``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import yaml

from harness.benchmarks._common import out_dir, tracked_note
from harness.core import jsonout
from harness.study import reading_search as rs
from harness.study.selection import (
    add_stage_arguments,
    confirmation_results,
    run_selection,
    run_stage,
    write_selection,
)

NAME = "reading"
HELP = "pre-registered selection (and confirmation) of BetaDescPrune's default reading; results/reading/"
OUT_SUB = "reading"  # under the default --out


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
        ("round two − round one", {"method": "betadesc", "variant": "default"},
         {"method": "betadesc", "variant": "r1"}),
        ("descriptor gain: betadesc − nodesc (defaults)", {"method": "betadesc", "variant": "default"},
         {"method": "betadesc-nodesc", "variant": "default"}),
        ("Beta gain without descriptors: nodesc − nodesc-nobeta", {"method": "betadesc-nodesc", "variant": "default"},
         {"method": "betadesc-nodesc-nobeta", "variant": "default"}))),
}


def select(args) -> int:
    out = out_dir(args, OUT_SUB)  # created and probed before any work
    rnd = ROUNDS[args.round]
    config = Path(args.config)
    raw = yaml.safe_load(config.read_text())
    space = rs.search_space(raw, interval=rnd.interval, searched=rnd.searched, prefix=rnd.prefix)
    steps, incumbents, times = run_selection(config, raw, space, args.workers)
    md = write_selection(out, f"selection{rnd.suffix}", config, space, steps, incumbents, times)
    print(md)
    print("selected:", jsonout.dumps(rs.selected_values(space, incumbents)))
    print(f"wrote {out / f'selection{rnd.suffix}.md'} and .json{tracked_note(out)}")
    return 0


def confirm(args) -> int:
    out = out_dir(args, OUT_SUB)  # created and probed before any work
    rnd = ROUNDS[args.round]
    raw, df, seconds = confirmation_results(args)
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
    out = out_dir(args, OUT_SUB)  # created and probed before any work
    from harness.io.scenes import load_scene
    from harness.study import directions as dirs

    scenes = [s.strip() for s in args.scenes.split(",") if s.strip()]
    rows = []
    for name in scenes:
        t0 = time.perf_counter()
        found = dirs.directions(load_scene(name))
        rows += [{"scene": name, **d.__dict__} for d in found]
        print(f"{name}: {time.perf_counter() - t0:.1f} s", flush=True)
    (out / "directions.json").write_text(jsonout.dumps(rows, indent=2) + "\n")
    md = directions_markdown(rows, scenes)
    (out / "directions.md").write_text(md)
    print(md)
    print(f"wrote {out / 'directions.md'} and .json{tracked_note(out)}")
    return 0


def directions_markdown(rows: list[dict], scenes: list[str]) -> str:
    from harness.study.directions import PAPER_DIRECTION

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
    add_stage_arguments(parser, "select the reading, confirm it, or measure the readings' directions",
                        "the round's, ctc_configs/study/reading[2].yaml for select, "
                        "reading[2]_confirm.yaml for confirm",
                        extra_stages=("directions",))
    parser.add_argument("--scenes", default=DIRECTION_SCENES, help="directions: comma-separated scenes")
    parser.add_argument("--round", type=int, choices=sorted(ROUNDS), default=1,
                        help="selection round (1: ctc_configs/study/reading.yaml, 2: reading2.yaml)")


def run(args) -> int:
    if args.stage == "directions":
        return directions(args)
    rnd = ROUNDS[args.round]
    return run_stage(args, rnd.config, rnd.confirm, select, confirm)
