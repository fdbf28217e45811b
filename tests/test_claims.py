"""The claims table (harness/report/claims.py, verdicts.py): the verdict rules by hand, every claim on
synthetic results with known differences, and the table through `harness tables`."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from harness.report.results import to_frame
from harness.report.tabledata import Missing
from harness.study import claims, verdicts
from harness.study.verdicts import INF, Estimate, combine, outcome, verdict_average, verdict_per_scene
from methods.registry import get_pruner

VIEWS = 8
NOISE = np.array([0.1, -0.1, 0.05, -0.05, 0.2, -0.2, 0.0, 0.0])  # mean 0, sd ≈ 0.12: intervals ≈ ±0.1


# --------------------------------------------------------------------------- verdict rules by hand
def test_outcome_against_a_band():
    band = (0.0, 1.6)
    assert outcome(Estimate(1.0, 0.5, 1.5, 8), band) == "holds"
    assert outcome(Estimate(2.0, 1.7, 2.3, 8), band) == "fails"  # entirely above the band
    assert outcome(Estimate(-1.0, -1.5, -0.5, 8), band) == "fails"  # entirely below
    assert outcome(Estimate(0.2, -0.1, 0.5, 8), band) == "unclear"
    assert outcome(Estimate(1.0, 0.5, 1.7, 8), band) == "unclear"
    assert outcome(Estimate(1.0, np.nan, np.nan, 1), band) == "holds"  # one value: judged by itself
    assert outcome(Estimate(np.nan, np.nan, np.nan, 0), band) == "unclear"
    assert outcome(Estimate(-3.0, -4.0, -2.0, 8), (-5.15, INF)) == "holds"


def test_verdicts_from_scenes_and_from_the_pool():
    assert combine(["holds", "holds"]) == "holds" and combine(["holds", "fails"]) == "fails"
    assert combine(["holds", "unclear"]) == "unclear"
    assert verdict_per_scene({"a": "holds", "b": "holds"}) == "holds"
    assert verdict_per_scene({"a": "fails", "b": "fails"}) == "fails"
    assert verdict_per_scene({"a": "holds", "b": "fails", "c": "unclear"}) == "mixed"
    assert verdict_per_scene({"a": "holds", "b": "unclear"}) == "inconclusive"
    assert verdict_average("holds") == "holds" and verdict_average("unclear") == "inconclusive"


@given(st.lists(st.sampled_from(["holds", "fails", "unclear"]), min_size=1, max_size=6), st.randoms())
def test_per_scene_verdict_ignores_scene_order(outcomes, rnd):
    shuffled = outcomes[:]
    rnd.shuffle(shuffled)
    a = verdict_per_scene({f"s{i}": o for i, o in enumerate(outcomes)})
    assert a == verdict_per_scene({f"s{i}": o for i, o in enumerate(shuffled)})
    assert (a == "mixed") == ("holds" in outcomes and "fails" in outcomes)


def test_pooled_is_over_scene_means():
    p = verdicts.pooled({"a": Estimate(1.0, 0.9, 1.1, 8), "b": Estimate(3.0, 2.9, 3.1, 8)})
    assert p.mean == 2.0 and p.n == 2  # two scenes: t(0.975, 1) = 12.71 on s/√2 = 1
    assert (p.lo, p.hi) == (pytest.approx(2 - 12.7062047), pytest.approx(2 + 12.7062047))
    one = Estimate(1.0, 0.9, 1.1, 8)
    assert verdicts.pooled({"a": one}) == one


# --------------------------------------------------------------------------- synthetic study
def _params(method, **over):
    return json.dumps({**get_pruner(method).parse_params().to_dict(), **over}, sort_keys=True)


def _rows(scene, method, ratio, psnr, variant="default", splats=1000, **over):
    base = np.broadcast_to(np.asarray(psnr, float), (VIEWS,)) + NOISE
    return [dict(run="t", scene=scene, label=scene.upper(), kind="object-centric", frame="", method=method,
                 variant=variant, params=_params(method, **over), ratio=ratio, keep=round(1 - ratio, 9),
                 view=f"v{i}", status="ok", psnr=float(p), ssim=0.95, lpips=0.05, splats_in=splats,
                 splats_out=int(splats * (1 - ratio)), score_s=1.0) for i, p in enumerate(base)]


def _study(gain_a=2.0, gain_b=-3.0, big=False):
    """Two scenes: descriptors help on A (+gain_a) and hurt on B (gain_b) at every keep and at 20 %."""
    rows = []
    for scene, gain in (("a", gain_a), ("b", gain_b)):
        n = 2_000_000 if big and scene == "a" else 1000
        for r in (0.1, 0.2, 0.3, 0.5, 0.7):
            full = 40.0 - 10 * r
            rows += _rows(scene, "betadesc", r, full, splats=n)
            rows += _rows(scene, "lightgs", r, full + (1.0 if r < 0.3 else -0.5), splats=n)
            if r in (0.2, 0.3, 0.5, 0.7):
                rows += _rows(scene, "betadesc-nodesc", r, full - gain, splats=n)
        rows += _rows(scene, "betadesc-nobeta", 0.2, 30.0, splats=n)
        rows += _rows(scene, "betadesc-nodesc-nobeta", 0.2, 37.0 - gain, splats=n)
        for v, d in ((0.1, 0.0), (0.3, 0.1)):  # the literal sweep around the default 0.2
            rows += _rows(scene, "betadesc", 0.3, 37.0 + d, variant=f"voxel={v:g}", splats=n, voxel=v)
        rows += _rows(scene, "betadesc", 0.3, 36.0, variant="preset=flat", splats=n, preset="flat")
    return to_frame(rows)


def _by_key(df, **kw):
    return {r.key: r for r in claims.results(df, **kw)}


def test_every_claim_on_a_synthetic_study():
    res = _by_key(_study(), overhead={"scenes": [{"scene": "a", "overhead_pct": [5.0, 6.0, 7.0]},
                                                 {"scene": "b", "overhead_pct": [40.0, 41.0, 42.0]}]})
    # Table 1: 1 dB behind LightGS at 10/20 % (within 5.15) on both scenes; no large scene
    assert res["t1-competitive-10%"].verdict == "holds"
    assert res["t1-competitive-10%"].pooled["BetaDesc − best camera-aware"].mean == pytest.approx(-1.0)
    assert res["t1-large-high"].verdict == "not testable here" and "1,000,000" in res["t1-large-high"].why
    # Table 2: descriptors help on A, hurt on B -> mixed; Beta helps everywhere -> holds
    assert res["t2-descriptors"].verdict == "mixed"
    assert res["t2-beta"].verdict == "holds" and res["t2-beta-nodesc"].verdict == "holds"
    assert res["t2-best"].verdict == "mixed"
    names = [n for n, _ in res["t2-best"].per_scene["A"]]
    assert len(names) == 3 and all(n.startswith("BetaDescPrune − ") for n in names)
    # Table 3: the pooled gain over two scenes (+2, −3) has a huge interval -> inconclusive; heterogeneity holds
    assert res["t3-keep-0.7"].verdict == "inconclusive" and res["t3-keep-0.7"].pooled[
        "with − without descriptors"
    ].mean == pytest.approx(-0.5)
    assert res["heterogeneity"].verdict == "holds"
    gap = res["t3-gap"]  # |Δ| ≤ 1.6 at all three keeps: +2 on A, −3 on B are outside on every keep
    assert [n for n, _ in gap.per_scene["A"]] == [f"with − without descriptors, keep {k:g}" for k in (0.7, 0.5, 0.3)]
    assert gap.scene_outcome("A") == "fails" and gap.scene_outcome("B") == "fails"
    assert res["t3-monotonic"].verdict == "holds" and res["t3-ssim"].verdict == "holds"
    # sensitivity: voxel 0.2 (default) − 0.1 = 0, 0.3 − 0.1 = +0.1: inside ±0.2 on every scene -> holds
    vox = res["voxel-literal"]
    assert vox.verdict == "holds" and set(vox.pooled) == {"voxel 0.2 − 0.1", "voxel 0.3 − 0.1"}
    assert vox.pooled["voxel 0.3 − 0.1"].mean == pytest.approx(0.1)
    assert res["voxel-percent"].verdict == "not testable here" and "voxel=0.01" in res["voxel-percent"].why
    presets = res["presets"]
    assert presets.verdict == "not testable here" and presets.pooled["preset flat − default"].mean == pytest.approx(
        -1.0
    )
    # runtime: 6 % on A, 41 % on B: pooled 23.5 % with a huge interval (2 scenes) -> inconclusive
    assert res["runtime"].verdict == "inconclusive" and res["runtime"].pooled["overhead %"].mean == pytest.approx(23.5)


def test_claims_follow_the_data():
    both_help = _by_key(_study(gain_a=1.0, gain_b=1.2), overhead={})
    assert both_help["t2-descriptors"].verdict == "holds"
    assert both_help["heterogeneity"].verdict == "fails"  # every scene on the same side
    assert both_help["t3-keep-0.5"].verdict == "inconclusive"  # 1.0, 1.2: t over 2 scenes is wide
    assert both_help["runtime"].verdict == "not testable here"
    big = _by_key(_study(big=True), overhead={})
    large = big["t1-large-high"]
    assert list(large.per_scene) == ["A"] and large.verdict == "holds"  # 0.5 dB ahead of LightGS at 30 %
    assert "large = ≥ 1,000,000 splats: A" in large.note


def test_missing_cells_are_named():
    df = _study()
    res = _by_key(df[df["method"] != "betadesc-nobeta"], overhead={})
    assert res["t2-beta"].verdict == "not testable here" and "betadesc-nobeta at 20%" in res["t2-beta"].why
    none = claims.table_claims(df[df["method"] == "lightgs"], overhead={})
    assert isinstance(none, Missing) and "no claim of the paper is testable" in none.reason


def test_table_layout_and_tidy_rows(tmp_path):
    t = claims.table_claims(_study(), overhead={})
    assert list(t.disp.columns) == ["claim", "paper", "at", "claimed band", "measured: pooled over scenes",
                                    "per scene (✓ holds, ✗ fails, ? unclear)", "verdict"]
    assert t.disp.loc["t2-descriptors", "verdict"] == "mixed"
    assert "A +2.00 [" in t.disp.loc["t2-descriptors", "per scene (✓ holds, ✗ fails, ? unclear)"]
    row = t.tidy[(t.tidy["key"] == "t2-descriptors") & (t.tidy["scene"] == "B")].iloc[0]
    assert row["mean"] == pytest.approx(-3.0) and row["outcome"] == "fails" and row["n"] == VIEWS
    assert any("Student-t" in n and f"n = {VIEWS}" in n for n in t.notes)
    assert math.isinf(t.tidy["band_high"].max())


def test_claims_table_through_harness_tables(tmp_path):
    from harness.cli import main
    from harness.report.results import write_results

    write_results(_study(), tmp_path)
    assert main(["tables", str(tmp_path), "--tables", "claims", "keep", "sensitivity", "--plots"]) == 0
    md = (tmp_path / "tables" / "claims.md").read_text()
    assert "| t2-descriptors |" in md and "mixed" in md
    csv = pd.read_csv(tmp_path / "tables" / "claims.csv")
    assert {"key", "scene", "mean", "ci_low", "ci_high", "verdict"} <= set(csv.columns)
