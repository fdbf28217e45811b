"""Round two of the virtual rig's pre-registered selection: where its cameras stand (rule:
``ctc_configs/study/virtualrig2.yaml``, verbatim in its header; confirmation scenes:
``ctc_configs/study/virtualrig2_confirm.yaml``); ``harness bench virtualrig select|confirm --round 2``.

* :func:`select` walks the rule's two axes (``positions``, ``support``) from the round-one placement
  with the selection engine of round one (:func:`harness.study.selection.run_selection`; 95 % t
  intervals; axes that do not change a scene's renders judged on the scenes they change) and writes
  ``selection2.md`` / ``.json`` and ``selected2.json``.
* :func:`confirm` runs the confirmation config with one more entry, the selected parameters
  (variant ``selected``), then applies the rule's Adoption step: per confirmation scene, the paired
  difference PSNR(selected) − PSNR(start) at 30 % over the shifted and independent views pooled
  (:func:`non_inferiority`); a scene whose 95 % t interval reaches −0.5 dB or below revokes every
  selected value that changes its cameras (:func:`axes_changing`: the rig with that one value
  changed differs from the start's). Writes ``confirmation2.md`` (every protocol and ratio against
  LightGS and opacity, the test, the decision) and ``adopted2.json``.
* :func:`rho` (``harness bench virtualrig rho``): the goal "Spearman ρ with LightGS significance ≥
  :data:`RHO_GOAL` on every scene", render-free, as ``harness diagnose`` computes it (LightGS over
  the scene's default-rig training views, 16 at 512 px; the virtual rig with its defaults), for the
  scenes of ``--scenes``: ``rho.md`` / ``.json``, each scene ``met`` or ``not met``.
"""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from harness.benchmarks._common import out_dir, tracked_note
from harness.core import jsonout
from harness.core.paths import REPO_ROOT as REPO
from harness.io.files import atomic_write_text
from harness.report.results import read_results
from harness.study import reading_search as rs
from harness.study.paired import compare
from harness.study.selection import harness_run, run_selection, write_selection

RULE_PROTOCOLS = ("shifted", "independent")
RATIO = 0.3
MARGIN_DB = 0.5
RHO_GOAL = 0.9
RHO_SCENES = "bonsai-7k,bonsai-7k-mini,luigi,grape-small,playbot,synth-room,synth-statue"
PREFIX = "vr2"


def rule_space(raw: dict) -> rs.SearchSpace:
    return rs.search_space(raw, "virtual-rig", reference={"method": "lightgs"}, prefix=PREFIX, interval="t",
                           protocols=RULE_PROTOCOLS)


def select(args, out_sub: str) -> int:
    out = out_dir(args, out_sub)
    config = Path(args.config)
    raw = yaml.safe_load(config.read_text())
    space = rule_space(raw)
    steps, chosen, times = run_selection(config, raw, space, args.workers, ignore_unchanged=True,
                                        cache=args.cache)
    md = write_selection(out, "selection2", config, space, steps, chosen, times)
    values = rs.selected_values(space, chosen)["virtual-rig"]
    atomic_write_text(out / "selected2.json", jsonout.dumps({"start": dict(space.start), "selected": values},
                                                         indent=2) + "\n")
    print(md)
    print("selected:", jsonout.dumps(values))
    print(f"wrote {out / 'selection2.md'}, .json and selected2.json{tracked_note(out)}")
    return 0


def axes_changing(scene_name: str, lod, start: dict, selected: dict) -> list[str]:
    """The selected values whose change alone (on the start) moves the scene's virtual cameras."""
    from harness.io.scenes import load_scene
    from methods.virtualrig import VirtualRigParams, virtual_cameras

    scene = load_scene(scene_name, lod=lod)
    base = [c.to_dict() for c in virtual_cameras(scene, VirtualRigParams(**start))[1]]
    out = []
    for k, v in selected.items():
        if start.get(k) != v:
            cams = [c.to_dict() for c in virtual_cameras(scene, VirtualRigParams(**{**start, k: v}))[1]]
            if cams != base:
                out.append(k)
    return out


def non_inferiority(df, scene: str) -> tuple:
    """(paired selected − start, verdict) on the rule's views at 30 %: ``not changed`` (identical
    renders), ``non-inferior`` (interval above −0.5 dB) or ``inferior``."""
    sub = df[df["protocol"].isin(RULE_PROTOCOLS)]
    p = compare(sub, scene=scene, ratio=RATIO, candidate={"method": "virtual-rig", "variant": "selected"},
                reference={"method": "virtual-rig", "variant": "start"}, interval="t")
    if p.n and p.mean == 0 and p.half_width == 0:
        return p, "not changed"
    return p, ("non-inferior" if p.n and p.lo > -MARGIN_DB else "inferior")


def confirm(args, out_sub: str) -> int:
    out = out_dir(args, out_sub)
    config = Path(args.config)
    raw = yaml.safe_load(config.read_text())
    pick = json.loads((out / "selected2.json").read_text())
    start, selected = pick["start"], pick["selected"]
    run_raw = {**raw, "name": raw["name"] + "-selected",
               "methods": [*raw["methods"], {"name": "virtual-rig", "variant": "selected",
                                              "params": {**start, **selected}}]}
    output = REPO / raw["output"]
    staged = output / "confirm-selected.yaml"
    staged.parent.mkdir(parents=True, exist_ok=True)
    staged.write_text(f"# generated by `harness bench virtualrig confirm --round 2` from {config} and "
                      f"{out / 'selected2.json'}\n" + yaml.safe_dump(run_raw, sort_keys=False))
    seconds = harness_run(staged, args.workers, args.cache)  # always: its stages are cached, the selected entry is new
    df = read_results(output)
    scenes = [s if isinstance(s, str) else s["name"] for s in raw["scenes"]]
    lods = {s["name"]: s.get("lod") for s in raw["scenes"] if isinstance(s, dict)}
    revoked, lines = set(), []
    for s in scenes:
        p, verdict = non_inferiority(df, s)
        moved = axes_changing(s, lods.get(s), start, selected) if verdict != "not changed" else []
        if verdict == "inferior":
            revoked |= set(moved)
        lines.append(f"| {s} | {p.text()} ({p.n}/{p.n_excluded}) | {', '.join(moved) or '–'} | {verdict} |")
    adopted = {k: (start[k] if k in revoked else v) for k, v in selected.items()}
    md = _report(raw, df, scenes, lines, start, selected, adopted, revoked)
    atomic_write_text(out / "confirmation2.md", md)
    atomic_write_text(out / "adopted2.json", jsonout.dumps({"start": start, "selected": selected, "adopted": adopted,
                                                          "revoked": sorted(revoked)}, indent=2) + "\n")
    print(md)
    print(f"wrote {out / 'confirmation2.md'} and adopted2.json{tracked_note(out)}")
    print(f"run time {seconds:.0f} s")
    return 0


def _report(raw, df, scenes, lines, start, selected, adopted, revoked) -> str:
    side = raw.get("protocol", {}).get("longest_side", "?")
    sel, st = {"method": "virtual-rig", "variant": "selected"}, {"method": "virtual-rig", "variant": "start"}
    md = [f"`{raw['name']}`: confirmation of the round-two selection (rule: ctc_configs/study/virtualrig2.yaml) "
          f"on scenes no choice was made on, {side} px, PSNR. D = mean paired per-view PSNR difference (dB) "
          "[95 % t interval] (views used/excluded).", "",
          f"Start: `{jsonout.dumps(start)}`; selected: `{jsonout.dumps(selected)}`.", "",
          f"## Adoption: non-inferiority of selected − start at {RATIO:.0%}, shifted and independent views pooled "
          f"(adopted unless the interval's lower bound is at or below −{MARGIN_DB:g} dB on a scene the value "
          "changes)", "", "| scene | selected − start [CI] (n/x) | values that change its cameras | verdict |",
          "|---|---|---|---|", *lines, "",
          f"**Adopted**: `{jsonout.dumps(adopted)}`" + (f" (revoked: {', '.join(sorted(revoked))})" if revoked else
                                                     " (every selected value)"), ""]
    ratios = sorted(set(float(r) for r in df["ratio"].dropna()))
    for proto in dict.fromkeys(df["protocol"].dropna()):
        sub = df[df["protocol"] == proto]
        for title, ref in (("vs LightGSPrune", {"method": "lightgs"}), ("vs opacity", {"method": "opacity"})):
            md += [f"### {proto}: {title}", "",
                   rs.confirmation_markdown(sub, scenes, ratios, [("selected", sel), ("start", st)], ref, "t")]
    return "\n".join(md)



def rho(args, out_sub: str) -> int:
    """Spearman ρ of the virtual rig's score with LightGS significance per scene (module docstring)."""
    from scipy.stats import spearmanr

    from harness.io.scenes import load_scene
    from harness.views.rigs import training_views
    from methods import PruneContext, get_pruner
    from methods.diagnose import lightgs_significance

    out = out_dir(args, out_sub)
    rows = []
    for name in [s.strip() for s in args.scenes.split(",") if s.strip()]:
        scene = load_scene(name, lod=0 if name == "playbot" else None)
        sig = lightgs_significance(scene, training_views(name, scene), longest_side=512)
        score = get_pruner("virtual-rig").score(scene, PruneContext())
        r = float(spearmanr(score, sig)[0])
        rows.append({"scene": name, "splats": len(scene), "rho": r, "met": r >= RHO_GOAL})
        print(f"{name}: rho {r:+.3f}", flush=True)
    md = ["Spearman ρ of the virtual rig's score (its defaults) with LightGS significance over each scene's "
          f"default-rig training views (16, 512 px), as `harness diagnose`; goal ρ ≥ {RHO_GOAL:g} on every scene.", "",
          "| scene | splats | ρ | goal |", "|---|---|---|---|"]
    md += [f"| {r['scene']} | {r['splats']:,} | {r['rho']:+.3f} | {'met' if r['met'] else 'not met'} |" for r in rows]
    md += ["", f"Every scene: {'met' if all(r['met'] for r in rows) else 'not met'}."]
    atomic_write_text(out / "rho.md", "\n".join(md) + "\n")
    atomic_write_text(out / "rho.json", jsonout.dumps(rows, indent=2) + "\n")
    print("\n".join(md))
    print(f"wrote {out / 'rho.md'} and .json{tracked_note(out)}")
    return 0
