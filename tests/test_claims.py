"""The claims table's verdict rules (harness/study/rules.py) by hand, and every claim type and edge on
small synthetic result tables whose differences are known (harness/study/claims.py, verdicts.py)."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from harness.report.meta import Estimate
from harness.report.results import to_frame
from harness.report.tabledata import Missing
from harness.study import claims, rules
from harness.study.claim_list import CLAIMS
from harness.study.rules import INF
from methods.registry import get_pruner

VIEWS = 8
NOISE = np.array([0.1, -0.1, 0.05, -0.05, 0.2, -0.2, 0.0, 0.0])  # mean 0, s = 0.124
SCENES = ("s1", "s2", "s3", "s4", "s5")


# --------------------------------------------------------------------------- the rules by hand
def test_inside_and_outside_match_the_interval_at_every_level():
    e = Estimate(1.0, 0.2, 7, 8)
    for alpha in (0.025, 0.005, 0.0025):
        lo, hi = e.interval(alpha)
        assert hi - 1.0 == pytest.approx(stats.t.ppf(1 - alpha, 7) * 0.2)
        for band in ((0.0, INF), (0.5, INF), (-INF, 1.2), (0.6, 1.5), (1.1, 2.0), (-3.0, 0.2)):
            inside = band[0] < lo and hi < band[1]
            outside = hi < band[0] or lo > band[1]
            assert (rules.p_inside(e, band) <= alpha) == inside, (alpha, band)
            assert (rules.p_outside(e, band) <= alpha) == outside, (alpha, band)


def test_p_values_by_hand():
    e = Estimate(1.0, 0.5, 4, 5)  # t against 0: 2, four d.f.
    assert rules.p_inside(e, (0.0, INF)) == pytest.approx(stats.t.sf(2.0, 4))
    assert rules.p_outside(e, (0.0, INF)) == pytest.approx(stats.t.cdf(2.0, 4))
    assert rules.p_inside(e, (-1.0, 1.5)) == pytest.approx(max(stats.t.sf(4.0, 4), stats.t.sf(1.0, 4)))  # TOST
    assert rules.p_outside(e, (1.5, 3.0)) == pytest.approx(stats.t.sf(1.0, 4))
    exact = Estimate(2.0, 0.0, 7, 8)  # every view differs by exactly 2
    assert rules.p_inside(exact, (0.0, INF)) == 0.0 and rules.p_outside(exact, (0.0, INF)) == 1.0
    assert rules.p_inside(Estimate(0.0, 0.0, 7, 8), (0.0, INF)) == 1.0  # on the bound: no evidence
    assert rules.p_inside(Estimate(1.0, math.nan, 0, 1), (0.0, INF)) == 1.0  # one view: no interval


def test_holm_step_down_by_hand():
    # m = 4 at α = 0.025: levels 0.00625, 0.00833, 0.0125, 0.025 in p order
    assert rules.holm([0.001, 0.02, 0.007, 0.5]) == [0.025 / 4, None, 0.025 / 3, None]
    assert rules.holm([0.001, 0.002, 0.003, 0.004]) == [0.025 / 4, 0.025 / 3, 0.025 / 2, 0.025]
    assert rules.holm([0.01, 0.001]) == [0.025, 0.0125]
    assert rules.holm([0.2, 0.001]) == [None, 0.0125]


def test_marks_show_the_interval_that_decided_them():
    ests = [Estimate(2.0, 0.1, 7, 8), Estimate(-2.0, 0.1, 7, 8), Estimate(0.05, 0.1, 7, 8)]
    marks = rules.judge(ests, (0.0, INF))
    assert [m.outcome for m in marks] == ["holds", "fails", "unclear"]
    assert marks[2].alpha == 0.025 / 3  # an unclear mark shows the widest (Bonferroni) interval
    lo, hi = ests[2].interval(marks[2].alpha)
    assert lo < 0 < hi
    assert rules.family_verdict(marks) == "fails"
    assert rules.family_verdict(rules.judge(ests[:1] + ests[2:], (0.0, INF))) == "inconclusive"


def test_holm_makes_a_borderline_scene_unclear_among_many():
    # t = 3 on 7 d.f. (one-sided p 0.0099): holds alone, not among 8 tests (its level ≤ 0.025/8·…)
    lone = Estimate(0.3, 0.1, 7, 8)
    assert rules.judge([lone], (0.0, INF))[0].outcome == "holds"
    crowd = [lone] + [Estimate(0.01, 0.1, 7, 8)] * 7
    assert rules.judge(crowd, (0.0, INF))[0].outcome == "unclear"


def test_existence_and_effect_rules():
    up, down, flat = Estimate(2.0, 0.1, 7, 8), Estimate(-2.0, 0.1, 7, 8), Estimate(0.0, 0.1, 7, 8)
    assert rules.existence_verdict([up, down, flat, flat])[0] == "holds"
    assert rules.existence_verdict([up, up, up, up])[0] == "fails"
    assert rules.existence_verdict([up, flat, flat, flat])[0] == "inconclusive"
    assert rules.effect_bands(3.32) == {"direction": (0.0, INF), "size": (1.66, INF)}
    assert rules.overall(["holds", "fails"]) == "fails" and rules.overall(["holds", "holds"]) == "holds"
    assert rules.overall(["holds", "inconclusive"]) == "inconclusive"


def test_every_claim_has_a_type_a_quote_and_a_reason():
    assert {c.type for c in CLAIMS} == set(rules.TYPES)
    for c in CLAIMS:
        assert c.quote and c.reason and c.lines
        assert (c.type == rules.EFFECT) == bool(c.smallest) or c.key == "t1-large-high"
        if c.type == rules.EFFECT:
            assert c.unit in (rules.UNIVERSAL, rules.AVERAGE) and c.smallest > 0


# --------------------------------------------------------------------------- synthetic studies
def _params(method, **over):
    return json.dumps(get_pruner(method).parse_params(over).to_dict(), sort_keys=True)


def _rows(scene, method, ratio, psnr, variant="default", splats=1000, side=1024, ssim=0.95, **over):
    """Eight views of one cell: ``psnr`` plus the noise pattern rolled by the cell's name (so that
    paired differences vary from view to view)."""
    shift = sum(map(ord, method + variant + scene)) % VIEWS
    base = np.broadcast_to(np.asarray(psnr, float), (VIEWS,)) + np.roll(NOISE, shift)
    return [dict(run="t", scene=scene, label=scene.upper(), kind="object-centric", frame="", method=method,
                 variant=variant, params=_params(method, **over), ratio=ratio, keep=round(1 - ratio, 9),
                 view=f"v{i}", status="ok", psnr=float(p), ssim=ssim, lpips=0.05, splats_in=splats,
                 splats_out=int(splats * (1 - ratio)), score_s=1.0, width=side, height=side * 3 // 4)
            for i, p in enumerate(base)]


def _study(gains=None, beta=8.0, camera=1.0, scenes=SCENES, direction=None, side=1024, lightgs_inf=(),
           voxel=(0.0, 0.1), big=()):
    """Scenes where the full method scores 40 − 10·ratio; ``gains[scene]``: its descriptor gain
    (every keep, 20 %; a tuple: one per keep 0.7/0.5/0.3); ``beta``: its Beta gain; ``camera``: LightGS's lead
    at 10/20 %; ``direction``: the paper-direction variants' descriptor gain (None: not measured)."""
    gains = gains or {}
    rows = []
    for scene in scenes:
        g = gains.get(scene, 2.0)
        per_keep = dict(zip((0.3, 0.5, 0.7), g)) if isinstance(g, tuple) else {r: g for r in (0.2, 0.3, 0.5, 0.7)}
        per_keep.setdefault(0.2, per_keep[0.3])
        n = 2_000_000 if scene in big else 1000
        for r in (0.1, 0.2, 0.3, 0.5, 0.7):
            full = 40.0 - 10 * r
            rows += _rows(scene, "betadesc", r, full, "default", n, side)
            if r in per_keep:
                rows += _rows(scene, "betadesc-nodesc", r, full - per_keep[r], "default", n, side)
            if r == 0.2:
                rows += _rows(scene, "betadesc-nobeta", r, full - beta, "default", n, side)
                rows += _rows(scene, "betadesc-nodesc-nobeta", r, full - per_keep[r] - beta, "default", n, side)
            if direction is not None:  # paper-direction: its own betadesc and no-Beta cells; the no-descriptor
                pdir = full - per_keep.get(r, 0.0) + direction  # variants serve both readings
                rows += _rows(scene, "betadesc", r, pdir, "pdir", n, side, reading="paper-direction")
                if r == 0.2:
                    rows += _rows(scene, "betadesc-nobeta", r, pdir - beta, "pdir", n, side, reading="paper-direction")
            lead = camera if r < 0.3 else -0.5
            lossless = scene in lightgs_inf and r == 0.1  # LightGS lossless on every view
            rows += _rows(scene, "lightgs", r, np.inf if lossless else full + lead, splats=n, side=side)
        for v, d in zip((0.1, 0.3), voxel):  # sweep around voxel 0.2 at keep 0.7
            rows += _rows(scene, "betadesc", 0.3, 37.0 + d, f"voxel={v:g}", n, side, voxel=v)
        rows += _rows(scene, "betadesc", 0.3, 37.05, "voxel=0.2", n, side, voxel=0.2)
    return to_frame(rows)


def _evals(df, overhead=None, reading="paper-literal"):
    found = claims.evaluations(df, overhead if overhead is not None else {})
    return {k: by[reading] for k, by in found.items()}


def test_universal_claims_hold_fail_and_are_unclear_as_their_scenes_are():
    ev = _evals(_study())
    assert ev["t1-competitive-10%"].verdict == "holds"  # 1 dB behind on every scene, band > −5.15
    assert ev["t2-descriptors"].verdict == "holds" and ev["t2-best"].verdict == "holds"
    one_fails = _evals(_study(gains={"s3": -3.0}))
    assert one_fails["t2-descriptors"].verdict == "fails"  # 4 of 5 hold, one fails beyond Holm: fails
    marks = {r.scene: r.mark.outcome for r in one_fails["t2-descriptors"].rows}
    assert marks == {"s1": "holds", "s2": "holds", "s3": "fails", "s4": "holds", "s5": "holds"}
    unclear = _evals(_study(gains={s: 0.0 for s in SCENES}))
    assert unclear["t2-descriptors"].verdict == "inconclusive"
    assert {r.mark.outcome for r in unclear["t2-descriptors"].rows} == {"unclear"}
    far = _evals(_study(camera=12.0))  # LightGS 12 dB ahead everywhere: not competitive
    assert far["t1-competitive-20%"].verdict == "fails"


def test_three_scenes_are_underpowered_whatever_the_numbers():
    ev = _evals(_study(scenes=SCENES[:3], camera=30.0))
    for key in ("t1-competitive-20%", "t2-descriptors", "t3-keep-0.7", "t3-gap", "heterogeneity", "voxel-literal"):
        assert ev[key].verdict == "underpowered", key
        assert ev[key].rows and "3 scenes" in ev[key].why  # the numbers are still there
    assert ev["t2-beta"].verdicts == {"direction": "underpowered", "size": "underpowered"}


def test_a_lossless_comparator_is_capped_not_dropped():
    df = _study(lightgs_inf=("s1", "s2"))
    ev = _evals(df)["t1-competitive-10%"]
    rows = {r.scene: r for r in ev.rows}
    assert set(rows) == set(SCENES)  # both lossless scenes stay in the verdict
    assert rows["s1"].capped == VIEWS and rows["s1"].dropped == 0
    assert rows["s1"].est.mean == pytest.approx(39.0 - 100.0, abs=1e-9)  # LightGS capped at 100
    assert ev.verdict == "fails"
    # both sides identical (≥ 100 dB): the pair leaves and is counted
    both = df.copy()
    both.loc[(both["scene"] == "s1") & (both["ratio"] == 0.1) & (both["method"] == "betadesc"), "psnr"] = np.inf
    gone = {r.scene: r for r in _evals(both)["t1-competitive-10%"].rows}
    assert "s1" not in gone  # nothing left to compare on s1
    t = claims.table_claims(both, overhead={})
    counts = next(n for n in t.notes if n.startswith("near-identical view pairs"))
    assert f"{VIEWS} identical on both sides" in counts and f"{VIEWS} with one side" in counts  # s1 left, s2 capped
    assert any("left out, every view pair identical on both sides" in n and "S1 (8 pairs)" in n for n in t.notes)


def test_two_comparisons_disagreeing_and_the_comparison_that_decided():
    # gap within ±1.6 at keep 0.7 and 0.5 (+0.5) but −3 at keep 0.3 on every scene: the claim fails,
    # and every scene shows its keep 0.3 comparison
    df = _study(gains={s: (0.5, 0.5, -3.0) for s in SCENES})
    ev = _evals(df)["t3-gap"]
    assert ev.verdict == "fails"
    assert {p.name: p.mark.outcome for p in ev.pooled} == {
        "with − without descriptors, keep 0.7": "holds", "with − without descriptors, keep 0.5": "holds",
        "with − without descriptors, keep 0.3": "fails"}
    t = claims.table_claims(df, overhead={})
    per_scene = t.sections[1][1].loc["t3-gap"].iloc[1]
    assert per_scene.count("keep 0.3: −3.00") == 0 and per_scene.count("keep 0.3: -3.00") == len(SCENES)
    decisive = t.tidy[(t.tidy["key"] == "t3-gap") & t.tidy["decisive"] & (t.tidy["reading"] == "paper-literal")]
    assert set(decisive["comparison"]) == {"with − without descriptors, keep 0.3"}


def test_average_claims_pool_scenes_by_random_effects():
    gains = {"s1": 1.0, "s2": 1.5, "s3": 2.0, "s4": 2.5, "s5": 3.0}
    ev = _evals(_study(gains=gains))["t3-keep-0.7"]
    (p,) = ev.pooled
    assert p.est.mean == pytest.approx(2.0, abs=1e-9) and p.est.n == 5 and p.est.df == 4
    assert p.est.tau2 > 0 and p.est.pi[0] < p.est.mean - (p.est.interval()[1] - p.est.mean)
    assert ev.verdicts == {"direction": "holds", "size": "holds"}  # size band: > 1.63 / 2
    small = _evals(_study(gains={s: 0.3 for s in SCENES}))["t3-keep-0.7"]
    assert small.verdicts == {"direction": "holds", "size": "fails"} and small.verdict == "fails"
    spread = {"s1": 5.0, "s2": -4.0, "s3": 3.0, "s4": -2.0, "s5": 1.0}
    assert _evals(_study(gains=spread))["t3-keep-0.7"].verdicts["direction"] == "inconclusive"


def test_effect_size_claims_per_row_and_heterogeneity():
    ev = _evals(_study(beta=0.5))
    assert ev["t2-beta"].verdicts == {"direction": "holds", "size": "fails"}  # 0.5 < 3.32 / 2 on every scene
    assert ev["t2-beta"].verdict == "fails"
    het = _evals(_study(gains={"s1": 3.0, "s2": -3.0, "s3": 0.0, "s4": 0.0, "s5": 0.0}))["heterogeneity"]
    assert het.verdict == "holds"
    assert {r.scene: r.test for r in het.rows} == {"s1": "above 0", "s2": "below 0", "s3": "", "s4": "", "s5": ""}
    assert _evals(_study())["heterogeneity"].verdict == "fails"  # +2 everywhere: no scene hurts


def test_the_two_readings_side_by_side():
    df = _study(direction=-3.0)  # descriptors help under paper-literal, hurt under paper-direction
    found = claims.evaluations(df, {})
    assert found["t2-descriptors"]["paper-literal"].verdict == "holds"
    assert found["t2-descriptors"]["paper-direction"].verdict == "fails"
    row = found["t2-descriptors"]["paper-direction"].rows[0]  # the no-descriptor cells serve both readings
    assert (row.a, row.b) == ("betadesc:pdir@0.2", "betadesc-nodesc:default@0.2")
    t = claims.table_claims(df, overhead={})
    assert t.disp.loc["t2-descriptors", "verdict"] == claims.DEPENDS
    assert t.disp.loc["t1-competitive-10%", "verdict"] == "holds"  # the same under both
    only = claims.table_claims(_study(), overhead={})  # no paper-direction variants measured
    assert only.disp.loc["t2-descriptors", "verdict"] == "holds (paper-literal only)"
    assert "the run has no full (paper-direction)" in only.disp.loc["t2-descriptors", "paper-direction"]


def test_a_level_at_another_render_size_is_not_comparable():
    ev = _evals(_study(side=256))["t3-ssim"]
    assert ev.verdict == "not comparable (render size)" and "256 px" in ev.why and ev.pooled
    assert _evals(_study())["t3-ssim"].verdict == "holds"  # 0.95 > 0.87 at 1024 px


def test_sweeps_runtime_and_presets():
    ev = _evals(_study(), overhead={"timed": "end to end", "scenes": [
        {"scene": s, "overhead_pct": [10.0 + 3 * i, 11.0 + 3 * i, 12.0 + 3 * i], "added_s": [0.2, 0.21, 0.22]}
        for i, s in enumerate(SCENES)]})
    assert ev["voxel-literal"].verdict == "holds"  # 0.2 − 0.1 = +0.05, 0.3 − 0.1 = +0.1: inside ±0.2
    assert ev["voxel-percent"].verdict == "not testable here" and "voxel=0.02" in ev["voxel-percent"].why
    assert ev["presets"].verdict == "not testable here"
    assert ev["runtime-added"].verdict == "holds"  # 0.21 s ≤ 1.0 s
    assert ev["runtime-relative"].verdict == "inconclusive"  # 11–23 %: the interval straddles 16 %
    assert ev["runtime-relative"].pooled[0].est.mean == pytest.approx(17.0)


def test_missing_cells_are_named_and_an_empty_run_is_missing():
    df = _study()
    ev = _evals(df[df["method"] != "betadesc-nobeta"])
    assert ev["t2-beta"].verdict == "not testable here" and "nobeta (paper-literal) at 20%" in ev["t2-beta"].why
    assert isinstance(claims.table_claims(df[df["method"] == "lightgs"], overhead={}), Missing)


def test_csv_rows_carry_type_and_verdict_and_selection_scenes_are_marked():
    df = _study(scenes=("luigi", "s2", "s3", "s4", "s5"))
    t = claims.table_claims(df, overhead={})
    tidy = t.tidy
    assert list(tidy.columns) == claims.TIDY
    assert set(tidy["key"]) == {c.key for c in CLAIMS}
    assert tidy["type"].isin(rules.TYPES).all() and tidy["verdict"].ne("").all()
    assert tidy.loc[tidy["scene"] == "luigi", "selection_scene"].all()
    assert "LUIGI†" in t.sections[1][1].loc["t2-descriptors"].iloc[1]
    row = tidy[(tidy["key"] == "t2-descriptors") & (tidy["scene"] == "s2") & (tidy["reading"] == "paper-literal")]
    assert row["a"].iloc[0] == "betadesc:default@0.2" and row["b"].iloc[0] == "betadesc-nodesc:default@0.2"


def test_claims_table_through_harness_tables(tmp_path):
    from harness.cli import main
    from harness.report.results import write_results

    write_results(_study(), tmp_path)
    assert main(["tables", str(tmp_path), "--tables", "claims", "--plots"]) == 0
    md = (tmp_path / "tables" / "claims.md").read_text()
    assert "| t2-descriptors |" in md and "paper-direction" in md
    csv = pd.read_csv(tmp_path / "tables" / "claims.csv")
    assert {"key", "type", "verdict", "scene", "mean", "ci_low", "ci_high"} <= set(csv.columns)
