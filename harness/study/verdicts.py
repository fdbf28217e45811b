"""One claim (:mod:`harness.study.claim_list`) evaluated on a run under one reading: its estimates
per scene (:mod:`harness.study.claim_cells`), pooled where its type asks, and its verdict by the rules
of :mod:`harness.study.rules`.

Scenes enter a claim when the run has every cell of its comparisons there (k of them). Order of the
checks: a missing cell or a claim that cannot be tested as stated → "not testable here"; an absolute
level measured at another render size than the paper's → "not comparable (render size)"; fewer
than :data:`harness.study.rules.MIN_SCENES` scenes → "underpowered"; else the type's rule. The
numbers are computed and shown in every case but the first.
"""

from __future__ import annotations

import numpy as np

from harness.core import ratios
from harness.study import rules
from harness.study.claim_cells import POOLED, Cell, Evaluation, Row, Run, best_camera, roles
from harness.study.claim_list import LARGE_SPLATS, PAPER_LONGEST_SIDE, Claim
from harness.study.rules import AVERAGE, EFFECT, EQUIVALENCE, EXISTENCE, UNIVERSAL


def _specs(claim: Claim, run: Run, reading: str, ev: Evaluation):
    """[(name, a(scene) -> Cell | None, b(scene) -> Cell | None, metric)] of ``claim`` (None: the
    level of a), or [] with ``ev.why`` saying what the run lacks."""
    kind, *args = claim.what
    cells = roles(run, reading)

    def cell(role, ratio):
        got = cells.get(role)
        if got is None or got[1] is None:
            return None
        return Cell(got[0], got[1], ratio)

    def need(*wanted):
        absent = [f"{role} ({reading}) at {ratios.percent(r)}" for role, r in wanted
                  if (c := cell(role, r)) is None or not run.measured(c)]
        if absent:
            ev.why = "the run has no " + ", ".join(dict.fromkeys(absent))
        return not absent

    if kind in ("best-camera", "best-camera-large"):
        (r,) = args
        if not need(("full", r)):
            return []
        return [("BetaDesc − best camera-aware", lambda s: cell("full", r), lambda s: best_camera(run, s, r), "psnr")]
    if kind == "best":
        (r,) = args
        if not need(*((role, r) for role in ("full", "neither", "nodesc", "nobeta"))):
            return []
        return [(f"full − {role}", lambda s: cell("full", r), lambda s, role=role: cell(role, r), "psnr")
                for role in ("neither", "nodesc", "nobeta")]
    if kind == "pair":
        r, x, y = args
        if not need((x, r), (y, r)):
            return []
        return [(f"{x} − {y}", lambda s: cell(x, r), lambda s: cell(y, r), "psnr")]
    if kind == "gain":
        (keeps,) = args
        rs = [ratios.from_keep(k) for k in keeps]
        if not need(*((role, r) for r in rs for role in ("full", "nodesc"))):
            return []
        name = "with − without descriptors"
        return [(name if len(keeps) == 1 else f"{name}, keep {k:g}", lambda s, r=r: cell("full", r),
                 lambda s, r=r: cell("nodesc", r), "psnr") for k, r in zip(keeps, rs)]
    if kind == "monotonic":
        a, b, c = (ratios.from_keep(k) for k in (0.7, 0.5, 0.3))
        if not need(("full", a), ("full", b), ("full", c)):
            return []
        return [("keep 0.7 − 0.5", lambda s: cell("full", a), lambda s: cell("full", b), "psnr"),
                ("keep 0.5 − 0.3", lambda s: cell("full", b), lambda s: cell("full", c), "psnr")]
    if kind == "level":
        keep, metric = args
        r = ratios.from_keep(keep)
        if not need(("full", r)):
            return []
        if metric not in run.ok or run.ok[metric].isna().all():
            ev.why = f"the run measured no {metric.upper()}"
            return []
        return [(f"mean {metric.upper()}", lambda s: cell("full", r), None, metric)]
    if kind == "sweep":
        param, reference, values = args
        r = ratios.from_keep(0.7)
        base = cell("full", r)
        if base is None:
            ev.why = f"the run has no full ({reading}) at keep 0.7"
            return []
        ref = base.variant if reference is None else run.sweep_variant(base.method, base.variant, param, reference)
        found = {v: run.sweep_variant(base.method, base.variant, param, v) for v in values}
        absent = [f"{param}={v}" for v, name in [(reference, ref), *found.items()] if name is None]
        if absent:
            ev.why = f"the run has no {base.method} ({reading}) variant {', '.join(map(str, absent))} at keep 0.7"
            return []
        ref_text = "default" if reference is None else f"{reference:g}" if isinstance(reference, float) else reference
        return [(f"{param} {v:g} − {ref_text}" if isinstance(v, float) else f"{param} {v} − {ref_text}",
                 lambda s, n=name: Cell(base.method, n, r), lambda s: Cell(base.method, ref, r), "psnr")
                for v, name in found.items()]
    raise ValueError(f"unknown claim recipe {kind!r}")


def _rows(claim: Claim, run: Run, reading: str, ev: Evaluation, bench: dict | None) -> list[Row]:
    """Every (scene, comparison) estimate of the scenes that have all of the claim's cells."""
    if claim.what[0] == "bench":
        return _bench_rows(claim, run, ev, bench)
    specs = _specs(claim, run, reading, ev)
    out = []
    scenes = list(run.labels)
    if claim.what[0] == "best-camera-large":
        scenes = [s for s in scenes if run.splats(s) >= LARGE_SPLATS]
        ev.notes.append(f"large = ≥ {LARGE_SPLATS:,} splats: {', '.join(run.labels[s] for s in scenes) or 'none'}")
    for scene in scenes:
        got = []
        for name, a, b, metric in specs:
            ca, cb = a(scene), (b(scene) if b is not None else None)
            row = None
            if ca is not None and b is None:
                row = run.level(scene, ca, metric)
            elif ca is not None and cb is not None:
                row = run.diff(scene, ca, cb, metric)
            if row is not None and not row.est.n and row.dropped:
                ev.left_out[scene] = ev.left_out.get(scene, 0) + row.dropped
            if row is None or not row.est.n:
                break
            row.name = name
            got.append(row)
        if specs and len(got) == len(specs):
            out.extend(got)
    if ev.left_out:
        ev.notes.append("left out, every view pair identical on both sides (≥ 100 dB): " + ", ".join(
            f"{run.labels[s]} ({n} pairs)" for s, n in ev.left_out.items()))
    if specs and not out and not ev.why:
        ev.why = "no scene has every cell this claim needs"
    return out


def _bench_rows(claim: Claim, run: Run, ev: Evaluation, bench: dict | None) -> list[Row]:
    if not bench:
        ev.why = "no benchmark: run `harness bench methods --overhead --out results/bench` (overhead.json)"
        return []
    field = claim.what[1]
    by_scene = {r["scene"]: r for r in bench.get("scenes", []) if field in r}
    rows = [Row("overhead %" if field == "overhead_pct" else "added seconds", s, rules.of_values(by_scene[s][field]),
                "betadesc", "betadesc-nodesc") for s in run.labels if s in by_scene]
    if not rows:
        ev.why = f"the benchmark timed none of this run's scenes ({', '.join(by_scene) or 'none'})"
    ev.notes.append(f"{bench.get('timed', 'scoring only')}; {bench.get('repeats', '?')} interleaved rounds per "
                    f"scene ({bench.get('when', 'undated')})" + (f"; {bench['note']}" if bench.get("note") else ""))
    return rows


def _pool(rows: list[Row]) -> list[Row]:
    """One random-effects row per comparison over the scenes (none below two scenes)."""
    if len({r.scene for r in rows}) < 2:
        return []
    names = list(dict.fromkeys(r.name for r in rows))
    return [Row(n, POOLED, rules.pooled([r.est for r in rows if r.name == n])) for n in names]


def evaluate(claim: Claim, run: Run, reading: str, bench: dict | None = None) -> Evaluation:
    """``claim`` on ``run`` under ``reading`` (module doc)."""
    ev = Evaluation(claim, reading)
    ev.rows = _rows(claim, run, reading, ev, bench)
    if ev.why:
        return ev
    ev.k = len({r.scene for r in ev.rows})
    kind = claim.type
    if kind in (AVERAGE, EQUIVALENCE, EXISTENCE) or claim.unit == AVERAGE:
        ev.pooled = _pool(ev.rows)
    if kind == EXISTENCE:
        verdict, ups, downs = rules.existence_verdict([r.est for r in ev.rows])
        for r, u, d in zip(ev.rows, ups, downs):
            r.mark = u if u.outcome == rules.HOLDS else d if d.outcome == rules.HOLDS else u
            r.test = "above 0" if u.outcome == rules.HOLDS else "below 0" if d.outcome == rules.HOLDS else ""
        ev.verdict = verdict
    elif kind == EFFECT:
        for test, band in rules.effect_bands(claim.smallest).items():
            ev.verdicts[test] = _decide(claim.unit, ev, band, mark=test == "direction")
        ev.verdict = rules.overall(ev.verdicts.values())
    else:
        ev.verdict = _decide(UNIVERSAL if kind == UNIVERSAL else AVERAGE, ev, claim.band, mark=True)
    if ev.pooled and kind not in (EFFECT, EXISTENCE) and not any(p.mark for p in ev.pooled):
        for p, m in zip(ev.pooled, rules.judge([p.est for p in ev.pooled], claim.band)):
            p.mark = m
    if claim.untestable:
        ev.verdict, ev.why, ev.verdicts = "not testable here", claim.untestable, {}
    elif claim.what[0] == "level" and run_sides(run) - {PAPER_LONGEST_SIDE}:
        ev.verdict, ev.verdicts = "not comparable (render size)", {}
        ev.why = (f"measured at {', '.join(f'{s} px' for s in sorted(run_sides(run)))} longest side; the paper's "
                  f"level is at {PAPER_LONGEST_SIDE} px")
    elif ev.k < rules.MIN_SCENES:
        ev.verdict = "underpowered"
        ev.verdicts = {t: "underpowered" for t in ev.verdicts}
        ev.why = f"{ev.k} scene{'s' * (ev.k != 1)}: a verdict needs at least {rules.MIN_SCENES}"
    return ev


def run_sides(run: Run) -> set[int]:
    return set().union(*run.sides.values()) if run.sides else set()


def _decide(unit: str, ev: Evaluation, band, *, mark: bool) -> str:
    """The verdict of ``unit``'s rule on ``band``; ``mark``: keep the marks on the rows shown."""
    scene_marks = rules.judge([r.est for r in ev.rows], band)
    if mark:
        for r, m in zip(ev.rows, scene_marks):
            r.mark = m
    if unit == UNIVERSAL:
        return rules.family_verdict(scene_marks)
    pooled_marks = rules.judge([p.est for p in ev.pooled], band)
    if mark:
        for p, m in zip(ev.pooled, pooled_marks):
            p.mark = m
    return rules.family_verdict(pooled_marks)


def scene_outcome(ev: Evaluation, scene: str) -> tuple[str, Row]:
    """A scene's outcome over its comparisons and the row that decided it: a failing one (the
    clearest), else the weakest of the holding ones, else the unclear one with the least evidence."""
    rows = [r for r in ev.rows if r.scene == scene]
    band = ev.claim.band if ev.claim.type != EFFECT else rules.effect_bands(ev.claim.smallest)["direction"]
    outcome = rules.combine(r.mark.outcome for r in rows if r.mark)
    if ev.claim.type == EXISTENCE:
        return (rows[0].test or rules.UNCLEAR), rows[0]
    if outcome == rules.FAILS:
        pick = min((r for r in rows if r.mark.outcome == rules.FAILS), key=lambda r: rules.p_outside(r.est, band))
    else:
        pool = [r for r in rows if r.mark.outcome != rules.HOLDS] or rows
        pick = max(pool, key=lambda r: rules.p_inside(r.est, band))
    return outcome, pick


def finite(x) -> bool:
    return x is not None and bool(np.isfinite(x))
