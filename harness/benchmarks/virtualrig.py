"""`harness bench virtualrig select|confirm`: the pre-registered parameter selection of the
``virtual-rig`` pruner and of ``betadesc-vr``'s evidence weight (rule: ``ctc_configs/virtualrig.yaml``,
verbatim), and a quick confirmation on the other scenes (``ctc_configs/virtualrig_confirm.yaml``).

    harness bench virtualrig select   [--config ctc_configs/virtualrig.yaml] [--workers 2]
    harness bench virtualrig confirm  [--config ctc_configs/virtualrig_confirm.yaml] [--workers 2] [--run]

``select`` walks the virtual rig's axes with the engine of the reading selection
(:func:`harness.benchmarks.reading.run_selection`): reference ``lightgs``, results restricted to the
``shifted`` and ``independent`` protocols, values over the scoring budget ruled out, axes that do not
apply to a scene (identical renders) judged on the scenes they change. Then ``betadesc-vr``'s
``vr_weight`` axis on the selected rig. Writes ``results/virtualrig/selection.md`` and ``.json``.
``confirm`` writes ``results/virtualrig/<config name>.md`` (``virtualrig-confirm.md``; the
development run on the selection scenes, ``--config ctc_configs/virtualrig_dev.yaml``:
``virtualrig-dev.md``): per protocol, paired differences against LightGS, opacity and the
significance alone.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import yaml

from harness.benchmarks.reading import (
    add_stage_arguments,
    confirmation_results,
    run_selection,
    run_stage,
    write_selection,
)
from harness.core.paths import results_dir
from harness.report import reading_search as rs

NAME = "virtualrig"
HELP = "pre-registered selection (and a quick confirmation) of the virtual-rig pruner; results/virtualrig/"
OUT = results_dir() / "virtualrig"
RULE_PROTOCOLS = ("shifted", "independent")
#: the scoring budget of the rule: virtual pixels per scene (views × resolution²) at most 48 × 384²
PIXEL_BUDGET = 48 * 384 ** 2
CRITERION = ("Criterion: D = mean paired per-view PSNR difference vs lightgs at {ratio:.0%} pruning (dB) over "
             "the held-out views of the shifted and independent protocols pooled, with its 95 % "
             "percentile-bootstrap CI (10,000 resamples of the views, seed 0); `n` views used (`x` "
             "excluded at >= 100 dB).")


def in_budget(params: dict) -> bool:
    return params["views"] * params["resolution"] ** 2 <= PIXEL_BUDGET


def rule_views(df):
    return df[df["protocol"].isin(RULE_PROTOCOLS)]


def select(args) -> int:
    config = Path(args.config)
    raw = yaml.safe_load(config.read_text())
    ref = {"method": "lightgs"}
    rig_space = rs.search_space(raw, "virtual-rig", ref, prefix="vr")
    steps, rig, times = run_selection(config, raw, rig_space, args.workers, fixed_methods=["lightgs"],
                                      restrict=rule_views, eligible=in_budget, ignore_unchanged=True)
    rig_overrides = rs.overrides(rig_space, rig)
    beta_space = rs.search_space(raw, "betadesc-vr", ref, prefix="bvr")
    beta_space = replace(beta_space, start={**beta_space.start, **rig_overrides})
    b_steps, beta, b_times = run_selection(config, raw, beta_space, args.workers, fixed_methods=["lightgs"],
                                           restrict=rule_views)
    criterion = CRITERION.format(ratio=rig_space.ratio)
    md = write_selection(OUT, config, rig_space, steps, rig, {**times, **b_times}, criterion)
    b_md = rs.selection_markdown(beta_space, b_steps, beta, criterion)
    md += "\n## betadesc-vr (on the selected rig)\n\n" + b_md
    (OUT / "selection.md").write_text(md)
    summary = {"virtual-rig": {a.name: rig[a.name] for a in rig_space.axes},
               "betadesc-vr": {a.name: beta[a.name] for a in beta_space.axes}}
    (OUT / "selected.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(md)
    print("selected:", json.dumps(summary))
    return 0


def confirm(args) -> int:
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
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / f"{raw['name']}.md").write_text(text)
    print(text)
    if seconds is not None:
        print(f"run time {seconds:.0f} s")
    return 0


def add_arguments(parser) -> None:
    add_stage_arguments(parser, "the parameters", "virtualrig")


def run(args) -> int:
    return run_stage(args, "virtualrig", select, confirm)
