"""The ``claims`` table: every claim of the paper (:mod:`harness.study.claim_list`), tested as the
paper states it under both faithful readings, with a verdict.

Each claim is evaluated under ``paper-literal`` (the default: the formulas as written) and
``paper-direction`` (ℓ, s, u oriented as the prose says; :mod:`harness.study.verdicts`). Its verdict
is theirs when they agree, **depends on the reading** when they differ, and the one reading's when the
run measured only one (said so). The rules: :mod:`harness.study.rules` and ``docs/claims.md``.

Outputs: the ``.md`` has a first section with one row per claim (type, the paper's number, band,
the verdict under each reading and overall) and one section per reading with the numbers (pooled
over scenes where the type pools; per scene, each with the comparison that decided its mark;
selection scenes marked †). The ``.csv`` (:data:`TIDY`) has one row per estimate — (claim, reading,
comparison, scene or ``pooled over scenes``) — and one row per (claim, reading) without estimates
(``scene`` empty); every row carries the claim's ``type`` and ``verdict``, machine-readable.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from harness.report.tabledata import Missing, Table
from harness.study import rules
from harness.study.claim_cells import POOLED, READINGS, Run
from harness.study.claim_list import CLAIMS, SELECTION_SCENES
from harness.study.verdicts import Evaluation, evaluate, scene_outcome

DEPENDS = "depends on the reading"
SCENE_MARK = {rules.HOLDS: "✓", rules.FAILS: "✗", rules.UNCLEAR: "?", "above 0": "↑", "below 0": "↓"}
TIDY = ["key", "claim", "type", "unit", "quote", "lines", "paper", "at", "band_low", "band_high", "size_low", "reading",
        "verdict", "verdict_reading", "verdict_direction", "verdict_size", "k", "comparison", "test", "scene",
        "label", "selection_scene", "a", "b", "mean", "se", "df", "n", "alpha", "ci_low", "ci_high", "outcome",
        "decisive", "tau2", "pi_low", "pi_high", "dropped_identical", "capped", "why"]


def combined(verdicts: dict[str, str]) -> tuple[str, str]:
    """(verdict over the readings, a note when only one reading was testable)."""
    testable = {r: v for r, v in verdicts.items() if v != "not testable here"}
    if not testable:
        return "not testable here", ""
    values = set(testable.values())
    verdict = values.pop() if len(values) == 1 else DEPENDS
    return verdict, (f"{next(iter(testable))} only" if len(testable) < len(verdicts) else "")


def evaluations(df: pd.DataFrame, overhead: dict | None = None) -> dict[str, dict[str, Evaluation]]:
    """{claim key: {reading: its evaluation}} on one protocol's rows."""
    run = Run(df)
    bench = overhead if overhead is not None else read_overhead()
    return {c.key: {r: evaluate(c, run, r, bench) for r in READINGS} for c in CLAIMS}


def read_overhead() -> dict | None:
    """``results/bench/overhead.json`` (``harness bench methods --overhead``), or None."""
    from harness.core.paths import results_dir

    try:
        return json.loads((results_dir() / "bench" / "overhead.json").read_text())
    except (OSError, ValueError):
        return None


def _label(ev: Evaluation, scene: str, labels: dict) -> str:
    return labels.get(scene, scene) + ("†" if scene in SELECTION_SCENES else "")


def _verdict_text(ev: Evaluation) -> str:
    if ev.verdicts:
        text = ", ".join(f"{t}: {v}" for t, v in ev.verdicts.items())
        text = f"{ev.verdict} ({text})"
    else:
        text = ev.verdict
    return text + (f" — {ev.why}" if ev.why and ev.verdict != "holds" else "")


def _per_scene(ev: Evaluation, labels: dict) -> str:
    parts = []
    several = len({r.name for r in ev.rows}) > 1
    for scene in dict.fromkeys(r.scene for r in ev.rows):
        outcome, row = scene_outcome(ev, scene)
        alpha = row.mark.alpha if row.mark else rules.ALPHA
        name = f"{row.name}: " if several else ""
        parts.append(f"{_label(ev, scene, labels)} {name}{row.est.text(alpha, ev.claim.digits)} "
                     f"{SCENE_MARK.get(outcome, '?')}")
    return " · ".join(parts) or "–"


def _pooled(ev: Evaluation) -> str:
    out = []
    for p in ev.pooled:
        alpha = p.mark.alpha if p.mark else rules.ALPHA
        extra = [f"k = {p.est.n}"]
        if np.isfinite(p.est.tau2):
            extra.append(f"τ² = {p.est.tau2:.{ev.claim.digits}g}")
        if np.isfinite(p.est.pi[0]):
            extra.append(f"prediction [{p.est.pi[0]:+.{ev.claim.digits}f}, {p.est.pi[1]:+.{ev.claim.digits}f}]")
        mark = f" {SCENE_MARK[p.mark.outcome]}" if p.mark else ""
        out.append(f"{p.name}: {p.est.text(alpha, ev.claim.digits)}{mark} ({', '.join(extra)})")
    return "; ".join(out) or "–"


def _band_text(claim) -> str:
    if claim.type == rules.EXISTENCE:
        return "> 0 on some scenes, < 0 on others"
    if claim.type == rules.EFFECT:
        size = rules.effect_bands(claim.smallest)["size"][0]
        return f"direction > 0; size > {size:+g}"
    lo, hi = claim.band
    return f"≤ {hi:g}" if lo == -rules.INF else f"> {lo:+g}" if hi == rules.INF else f"in ({lo:+g}, {hi:+g})"


def table_claims(df: pd.DataFrame, overhead: dict | None = None):
    found = evaluations(df, overhead)
    if all(ev.verdict == "not testable here" and not ev.rows for by in found.values() for ev in by.values()):
        first = [f"{k}: {by[READINGS[0]].why}" for k, by in list(found.items())[:3]]
        return Missing("no claim of the paper is testable on these results: " + "; ".join(first))
    labels = dict(zip(df["scene"], df["label"])) if "label" in df else {}
    summary, sections, tidy, notes = [], [], [], []
    per_reading = {r: [] for r in READINGS}
    for c in CLAIMS:
        by = found[c.key]
        verdict, only = combined({r: ev.verdict for r, ev in by.items()})
        summary.append([c.key, f"{c.title} (L{c.lines[0]})", c.type, c.paper, c.at, _band_text(c),
                        *(_verdict_text(by[r]) for r in READINGS), verdict + (f" ({only})" if only else "")])
        for r, ev in by.items():
            per_reading[r].append([c.key, _pooled(ev), _per_scene(ev, labels), _verdict_text(ev)])
            tidy += _tidy(ev, verdict, labels)
        said = [dict.fromkeys(by[r].notes) for r in READINGS]
        notes += [f"{c.key}: {n}" for n in said[0] if all(n in x for x in said)]
        notes += [f"{c.key} ({r}): {n}" for r, x in zip(READINGS, said) for n in x if not all(n in y for y in said)]
    head = ["key", "claim", "type", "paper", "at", "claimed band", *READINGS, "verdict"]
    disp = pd.DataFrame(summary, columns=head).set_index("key")
    sections = [("verdicts: each claim under both faithful readings", disp)]
    for r in READINGS:
        sections.append((f"the numbers under {r}", pd.DataFrame(
            per_reading[r], columns=["key", "pooled over scenes (random effects, HKSJ interval)",
                                     "per scene (✓ holds, ✗ fails, ? unclear; ↑ ↓ above / below 0)", "verdict"]
        ).set_index("key")))
    frame = pd.DataFrame(tidy, columns=TIDY)
    dropped = int(frame["dropped_identical"].sum()) + sum(n for by in found.values() for ev in by.values()
                                                          for n in ev.left_out.values())
    capped = int(frame["capped"].sum())
    notes = [
        "intervals: Student t over a scene's paired views (per scene) or the HKSJ random-effects interval over "
        "scenes (pooled), each at the Holm level that decided its mark (95 % two-sided for a single test); "
        "rules: docs/claims.md (harness/study/rules.py)",
        f"† selection scene of the pre-registered reading rounds ({', '.join(SELECTION_SCENES)}): numbers there "
        "may be optimistically biased",
        f"near-identical view pairs: {dropped} identical on both sides (≥ 100 dB) left out, {capped} with one side "
        "≥ 100 dB kept with that side capped at 100 dB (counts over every row of the table)",
        *notes]
    caption = "n = views per scene, scenes pooled; " + notes[0].removeprefix("intervals: ")
    return Table(disp, notes[1:], frame, sections=sections, caption=caption)


def _tidy(ev: Evaluation, verdict: str, labels: dict) -> list[dict]:
    c = ev.claim
    base = {"key": c.key, "claim": c.title, "type": c.type, "unit": c.unit or c.type, "quote": c.quote,
            "lines": ",".join(map(str, c.lines)), "paper": c.paper, "at": c.at, "band_low": c.band[0],
            "band_high": c.band[1], "size_low": rules.effect_bands(c.smallest)["size"][0] if c.type == rules.EFFECT
            else np.nan, "reading": ev.reading, "verdict": verdict, "verdict_reading": ev.verdict,
            "verdict_direction": ev.verdicts.get("direction", ""), "verdict_size": ev.verdicts.get("size", ""),
            "k": ev.k, "why": ev.why}
    decisive = {id(scene_outcome(ev, s)[1]) for s in {r.scene for r in ev.rows}}
    out = []
    for r in [*ev.rows, *ev.pooled]:
        alpha = r.mark.alpha if r.mark else rules.ALPHA
        lo, hi = r.est.interval(alpha)
        out.append({**base, "comparison": r.name, "test": r.test, "scene": r.scene,
                    "label": POOLED if r.scene == POOLED else labels.get(r.scene, r.scene),
                    "selection_scene": r.scene in SELECTION_SCENES, "a": r.a, "b": r.b, "mean": r.est.mean,
                    "se": r.est.se, "df": r.est.df, "n": r.est.n, "alpha": alpha, "ci_low": lo, "ci_high": hi,
                    "outcome": r.mark.outcome if r.mark else "", "decisive": id(r) in decisive,
                    "tau2": r.est.tau2, "pi_low": r.est.pi[0], "pi_high": r.est.pi[1],
                    "dropped_identical": r.dropped, "capped": r.capped})
    if not out:
        out.append({**base, "comparison": "", "test": "", "scene": "", "label": "", "selection_scene": False,
                    "a": "", "b": "", "mean": np.nan, "se": np.nan, "df": 0, "n": 0, "alpha": np.nan,
                    "ci_low": np.nan, "ci_high": np.nan, "outcome": "", "decisive": False, "tau2": np.nan,
                    "pi_low": np.nan, "pi_high": np.nan, "dropped_identical": 0, "capped": 0})
    return out
