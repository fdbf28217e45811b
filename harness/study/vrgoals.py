"""The ``virtual_rig`` table: the camera-free virtual rig against its goals, per scene, for the view
protocol the table is built for, at 30 % pruning.

Goals (the project's, for the virtual rig; a goal applies under the protocols it names):

* **within 0.5 dB of LightGS** under ``shifted`` and ``independent``, every scene: Δ = mean paired
  per-view PSNR(virtual-rig) − PSNR(lightgs) ≥ −0.5 dB;
* **above LightGS** under ``independent`` and ``real`` on rooms: Δ > 0 (a room: a scene whose test
  rig is the room rig, :data:`harness.views.rigs.SCENE_RIGS`);
* **above opacity** under every protocol, every scene: mean paired PSNR(virtual-rig) −
  PSNR(opacity) > 0.

Reading decided here: a goal is judged on the mean paired difference, the statement's own quantity
("within 0.5 dB", "above"); its 95 % t interval is printed beside it, and ``(CI)`` marks a verdict
the interval agrees with (the whole interval on the goal's side), so a reader sees which verdicts
eight views could overturn. Each cell says ``met`` or ``not met`` plainly; a goal that does not
apply under the protocol says ``–``. Views with PSNR ≥ 100 dB on either side are left out, as in
every table. Spearman's ρ with LightGS significance is render-free and not in a run's results:
``harness diagnose SCENE --method virtual-rig`` prints it.
"""

from __future__ import annotations

import pandas as pd

from harness.report.tabledata import Missing, Table
from harness.study.paired import compare

RATIO = 0.3
MARGIN_DB = 0.5
METHOD, LIGHTGS, OPACITY = "virtual-rig", "lightgs", "opacity"
WITHIN = ("shifted", "independent")
ROOM_ABOVE = ("independent", "real")
SIDE = {m: {"method": m, "variant": "default"} for m in (METHOD, LIGHTGS, OPACITY)}


def _rooms() -> set[str]:
    from harness.views.rigs import SCENE_RIGS

    return {name for name, d in SCENE_RIGS.items() if d.rig == "room"}


def _verdict(p, threshold: float, strict: bool) -> str:
    """``met`` when the mean is above ``threshold`` (``strict``: >, else ≥), with ``(CI)`` when the
    whole interval is on the same side."""
    if p.n == 0:
        return "n/a"
    above = (lambda v: v > threshold) if strict else (lambda v: v >= threshold)
    ok = above(p.mean)
    agrees = above(p.lo) if ok else not above(p.hi)
    return ("met" if ok else "not met") + (" (CI)" if agrees else "")


def table_virtual_rig(df: pd.DataFrame):
    """The goals table of one protocol's results (module docstring)."""
    have = set(df["method"])
    if METHOD not in have or LIGHTGS not in have:
        return Missing(f"needs {METHOD} and {LIGHTGS} measured at {RATIO:.0%}")
    protocol = str(df["protocol"].iloc[0]) if "protocol" in df and len(df) else ""
    rooms = _rooms()
    rows, tidy = [], []
    for scene in dict.fromkeys(df["scene"]):
        label = df.loc[df["scene"] == scene, "label"].iloc[0] if "label" in df else scene
        vs_l = compare(df, scene=scene, ratio=RATIO, candidate=SIDE[METHOD], reference=SIDE[LIGHTGS])
        if vs_l.n == 0:
            continue
        goal, verdict = "–", "–"
        if protocol in WITHIN:
            goal, verdict = f"≥ −{MARGIN_DB:g} dB", _verdict(vs_l, -MARGIN_DB, strict=False)
        if protocol in ROOM_ABOVE and scene in rooms:
            above = _verdict(vs_l, 0.0, strict=True)
            goal, verdict = (f"{goal} and > 0 (room)", f"{verdict}; {above}") if goal != "–" else ("> 0 (room)", above)
        vs_o = compare(df, scene=scene, ratio=RATIO, candidate=SIDE[METHOD], reference=SIDE[OPACITY])
        o_text, o_verdict = (vs_o.text(), _verdict(vs_o, 0.0, strict=True)) if vs_o.n else ("n/a", "n/a")
        rows.append({"scene": label, "Δ vs LightGS [CI]": vs_l.text(), "goal": goal, "verdict": verdict,
                     "Δ vs opacity [CI]": o_text, "above opacity": o_verdict, "n": vs_l.n})
        for ref, p, v in ((LIGHTGS, vs_l, verdict), (OPACITY, vs_o, o_verdict)):
            if p.n:
                tidy.append({"scene": scene, "label": label, "protocol": protocol, "ratio": RATIO, "reference": ref,
                             "delta": p.mean, "ci_low": p.lo, "ci_high": p.hi, "n": p.n,
                             "n_excluded": p.n_excluded, "verdict": v})
    if not rows:
        return Missing(f"no scene has {METHOD} and {LIGHTGS} at {RATIO:.0%} on the same views")
    disp = pd.DataFrame(rows).set_index("scene")
    notes = [f"Δ = mean paired per-view PSNR difference at {RATIO:.0%} pruning [95 % t interval]; a verdict "
             "reads the mean (the goal's own quantity), (CI) where the whole interval agrees",
             f"goals: within {MARGIN_DB:g} dB of LightGS under shifted and independent; above it under "
             "independent and real on rooms; above opacity everywhere (– : no goal under this protocol)"]
    return Table(disp, notes, pd.DataFrame(tidy), caption=f"n = {int(disp['n'].min())}–{int(disp['n'].max())} "
                 "paired views per scene")
