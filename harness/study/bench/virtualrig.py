"""`harness bench virtualrig select|confirm`: the pre-registered parameter selection of the
``virtual-rig`` pruner and of ``betadesc-vr``'s evidence weight (rule: ``ctc_configs/study/virtualrig.yaml``,
verbatim), and a quick confirmation on the other scenes (``ctc_configs/study/virtualrig_confirm.yaml``).

    harness bench virtualrig select   [--config ctc_configs/study/virtualrig.yaml] [--workers 2] [--out DIR]
    harness bench virtualrig confirm  [--config ctc_configs/study/virtualrig_confirm.yaml] [--workers 2] [--run]
                                      [--out DIR]

``select`` walks the virtual rig's axes with the engine of the reading selection
(:func:`harness.study.selection.run_selection`): reference ``lightgs``, the views of the
``shifted`` and ``independent`` protocols pooled, values over the scoring budget ruled out, axes that
do not apply to a scene (identical renders) judged on the scenes they change. Then ``betadesc-vr``'s
``vr_weight`` axis on the selected rig. Writes ``selection.md``, ``.json`` and ``selected.json``.
``confirm`` writes ``<config name>.md`` (``virtualrig-confirm.md``; the development run on the
selection scenes, ``--config ctc_configs/study/virtualrig_dev.yaml``: ``virtualrig-dev.md``): per protocol,
paired differences against LightGS, opacity and the significance alone. Both write into ``--out``
(default ``runs/bench/virtualrig``; ``--out results/virtualrig`` updates the committed reports).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import yaml

from harness.benchmarks._common import out_dir, tracked_note
from harness.core import jsonout
from harness.io.files import atomic_write_text
from harness.study import reading_search as rs
from harness.study.selection import (
    add_stage_arguments,
    confirmation_results,
    run_selection,
    run_stage,
    write_selection,
)

NAME = "virtualrig"
HELP = "pre-registered selection (and a quick confirmation) of the virtual-rig pruner; results/virtualrig/"
OUT_SUB = "virtualrig"  # under the default --out
RULE_PROTOCOLS = ("shifted", "independent")
#: the scoring budget of the rule: virtual pixels per scene (views × resolution²) at most 48 × 384²
PIXEL_BUDGET = 48 * 384 ** 2


def in_budget(params: dict) -> bool:
    return params["views"] * params["resolution"] ** 2 <= PIXEL_BUDGET


def rule_space(raw: dict, method: str, prefix: str) -> rs.SearchSpace:
    """The rule's search of ``method``: D vs lightgs over the shifted and independent views pooled."""
    return rs.search_space(raw, method, reference={"method": "lightgs"}, prefix=prefix, protocols=RULE_PROTOCOLS)


def select(args) -> int:
    out = out_dir(args, OUT_SUB)  # created and probed before any work
    config = Path(args.config)
    raw = yaml.safe_load(config.read_text())
    rig_space = rule_space(raw, "virtual-rig", "vr")
    steps, rig, times = run_selection(config, raw, rig_space, args.workers, eligible=in_budget,
                                      ignore_unchanged=True)
    beta_space = rule_space(raw, "betadesc-vr", "bvr")
    beta_space = replace(beta_space, starts={"betadesc-vr": {**beta_space.start,
                                                             **rs.overrides(rig_space, rig["virtual-rig"])}})
    b_steps, beta, b_times = run_selection(config, raw, beta_space, args.workers)
    appendix = "\n## betadesc-vr (on the selected rig)\n\n" + rs.selection_markdown(beta_space, b_steps, beta)
    md = write_selection(out, "selection", config, rig_space, steps, rig, {**times, **b_times}, appendix)
    summary = {**rs.selected_values(rig_space, rig), **rs.selected_values(beta_space, beta)}
    atomic_write_text(out / "selected.json", jsonout.dumps(summary, indent=2) + "\n")
    print(md)
    print("selected:", jsonout.dumps(summary))
    print(f"wrote {out / 'selection.md'}, .json and selected.json{tracked_note(out)}")
    return 0


def confirm(args) -> int:
    out = out_dir(args, OUT_SUB)  # created and probed before any work
    raw, df, seconds = confirmation_results(args)
    scenes = [s["name"] if isinstance(s, dict) else s for s in raw["scenes"]]
    ratios = list(raw["ratios"])
    vr, bvr = {"method": "virtual-rig"}, {"method": "betadesc-vr", "variant": "default"}
    tables = [("vs LightGSPrune", {"method": "lightgs"},
               [("virtual-rig", vr), ("betadesc-vr", bvr), ("opacity", {"method": "opacity"}),
                ("betadesc", {"method": "betadesc"})]),
              ("vs opacity", {"method": "opacity"}, [("virtual-rig", vr), ("betadesc-vr", bvr)]),
              ("vs the significance alone (virtual-rig)", vr,
               [("betadesc-vr", bvr), ("betadesc-vr without descriptors",
                                       {"method": "betadesc-vr", "variant": "nodesc"})])]
    side = raw.get("protocol", {}).get("longest_side", "?")
    md = [f"`{raw['name']}` ({Path(args.config).name}): a quick run at {side} px, PSNR only — not the pre-registered "
          "evaluation. D = mean paired per-view PSNR difference (dB) [95 % bootstrap CI] (views used/excluded).", ""]
    for proto in dict.fromkeys(df["protocol"].dropna()):
        if not proto:
            continue
        sub = df[df["protocol"] == proto]
        for title, reference, sides in tables:
            md += [f"### {proto}: {title}", "", rs.confirmation_markdown(sub, scenes, ratios, sides, reference)]
    text = "\n".join(md)
    atomic_write_text(out / f"{raw['name']}.md", text)
    print(text)
    print(f"wrote {out / (raw['name'] + '.md')}{tracked_note(out)}")
    if seconds is not None:
        print(f"run time {seconds:.0f} s")
    return 0


def add_arguments(parser) -> None:
    add_stage_arguments(parser, "select the parameters, or confirm them; rho: the virtual rig's Spearman rho "
                        "with LightGS significance per scene against its goal",
                        "ctc_configs/study/virtualrig.yaml for select, virtualrig_confirm.yaml for confirm; "
                        "round 2: ctc_configs/study/virtualrig2.yaml, virtualrig2_confirm.yaml", extra_stages=("rho",))
    parser.add_argument("--scenes", default=None, help="rho: comma-separated scenes (default: the default "
                        "study's and the two generated ones)")
    parser.add_argument("--round", type=int, choices=(1, 2), default=1,
                        help="1: the rig's geometry and betadesc-vr's weight; 2: where the cameras stand")


def run(args) -> int:
    if args.stage == "rho":
        from harness.study import virtualrig_round2 as r2

        args.scenes = args.scenes or r2.RHO_SCENES
        return r2.rho(args, OUT_SUB)
    if args.round == 2:
        from harness.study import virtualrig_round2 as r2

        return run_stage(args, "virtualrig2.yaml", "virtualrig2_confirm.yaml",
                         lambda a: r2.select(a, OUT_SUB), lambda a: r2.confirm(a, OUT_SUB))
    return run_stage(args, "virtualrig.yaml", "virtualrig_confirm.yaml", select, confirm)
