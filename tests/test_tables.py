"""Tables from tidy results: means by hand, inf handling, the paper's layouts, and `harness tables`."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from harness.cli import main
from harness.core.names import file_name
from harness.report.results import read_results, to_frame, write_results
from harness.report.summary import summarise
from harness.report.tabledata import Missing
from harness.report.tables import build_tables, write_tables


def _rows():
    rows = []
    # scene A: two views. betadesc psnr 30/32 at 0.1, lightgs 40/inf at 0.1 (inf excluded), etc.
    spec = {
        ("betadesc", 0.1): (30.0, 32.0), ("betadesc", 0.2): (28.0, 28.0), ("betadesc", 0.3): (25.0, 27.0),
        ("betadesc", 0.5): (22.0, 22.0), ("betadesc", 0.7): (18.0, 20.0),
        ("lightgs", 0.1): (40.0, math.inf), ("lightgs", 0.2): (math.inf, math.inf), ("lightgs", 0.3): (29.0, 29.0),
        ("betadesc-nodesc", 0.2): (26.0, 26.0), ("betadesc-nodesc", 0.3): (24.0, 24.0),
        ("betadesc-nodesc", 0.5): (21.0, 21.0), ("betadesc-nodesc", 0.7): (19.0, 19.0),
        ("betadesc-nobeta", 0.2): (27.0, 27.0), ("betadesc-nodesc-nobeta", 0.2): (20.0, 20.0),
    }
    for (m, r), vals in spec.items():
        for v, p in enumerate(vals):
            rows.append(dict(run="t", scene="a", label="scene A", kind="object-centric", frame="", method=m,
                             variant="default", params="{}", ratio=r, keep=round(1 - r, 9), view=f"v{v}",
                             status="ok", psnr=p, ssim=0.9 + 0.001 * p / 10, lpips=0.1 - p / 1000,
                             splats_in=1000, splats_out=int(1000 * (1 - r)), score_s=2.0 if m == "betadesc" else 1.5))
    for preset, p in (("preset=flat", 24.0), ("voxel=0.02", 26.5)):
        rows.append({**rows[0], "variant": preset, "ratio": 0.3, "keep": 0.7, "psnr": p})
    # a second scene measured by the default variant only: must not enter the sensitivity means
    rows.append({**rows[0], "scene": "b", "label": "scene B", "ratio": 0.3, "keep": 0.7, "psnr": 99.0})
    rows.append({**rows[0], "method": "confsplat", "status": "skipped", "view": "", "psnr": np.nan,
                 "reason": "needs cameras"})
    return to_frame(rows)


def test_summary_excludes_inf_and_counts_it():
    s = summarise(_rows())
    lg = s[(s["method"] == "lightgs")].set_index("ratio")
    assert lg.loc[0.1, "psnr"] == 40.0 and lg.loc[0.1, "n_inf"] == 1 and lg.loc[0.1, "n"] == 2
    assert math.isinf(lg.loc[0.2, "psnr"]) and lg.loc[0.2, "n_inf"] == 2
    assert "confsplat" not in set(s["method"])  # skipped rows never enter means


def _t(name, df=None, **opts):
    return build_tables(_rows() if df is None else df, [name], **opts)[name]


def _cell(tidy, **where):
    m = tidy
    for k, v in where.items():
        m = m[np.isclose(m[k], v)] if isinstance(v, float) else m[m[k] == v]
    assert len(m) == 1, where
    return m.iloc[0]


def test_comparison_layout_and_values():
    t = _t("comparison", reference="lightgs")
    assert list(t.disp.columns.get_level_values("method").unique()) == ["LightGSPrune", "BetaDescPrune"]
    assert list(t.disp.columns.get_level_values("level")[:3]) == ["Low", "Mid", "High"]
    low = _cell(t.tidy, method="betadesc", ratio=0.1, metric="psnr", scene="a")
    assert low["mean"] == pytest.approx(31.0) and low["n"] == 2 and low["reference"] == "lightgs[default]"
    # lightgs at 10 %: 40 and inf -> the inf view is near-identical: left out of the mean and of Δ
    lg = _cell(t.tidy, method="lightgs", ratio=0.1, metric="psnr")
    assert lg["mean"] == 40.0 and lg["n_near_identical"] == 1 and math.isinf(lg["median"])
    assert low["delta"] == pytest.approx(30.0 - 40.0) and low["n_pairs"] == 1 and low["n_pairs_excluded"] == 1
    assert t.disp.loc[("scene A", "PSNR (↑)"), ("Camera-Aware Methods", "LightGSPrune", "Mid")] == "≥100‡"
    assert t.disp.loc[("scene A", "PSNR (↑)"), ("Our Method", "BetaDescPrune", "High")] == "26.00"
    assert any("‡" in n and "100 dB" in n for n in t.notes)


def test_comparison_markdown_is_one_table_per_metric_and_csv_is_tidy(tmp_path):
    """Issue 16: comparison.md had 17 flattened columns, comparison.csv three header rows."""
    write_tables(_rows(), tmp_path, ["comparison"], reference="lightgs")
    md = (tmp_path / "tables" / "comparison.md").read_text()
    assert [ln for ln in md.splitlines() if ln.startswith("#### ")] == [
        "#### PSNR (↑)", "#### SSIM (↑)", "#### LPIPS (↓)", "#### Kept splats · pruned .ply size"]
    # the size of each cell beside its quality (no bytes in these rows: "–")
    assert "| scene A | LightGSPrune | 900 splats · – | 800 splats · – | 700 splats · – |" in md
    headers = [ln for ln in md.splitlines() if ln.startswith("| Dataset")]
    assert headers and all(h == "| Dataset | Method | Low (10%) | Mid (20%) | High (30%) |" for h in headers)
    assert "|  | BetaDescPrune | 31.00 (Δ -10.00) |" in md  # one pair (the inf one left out): no interval
    csv = pd.read_csv(tmp_path / "tables" / "comparison.csv")
    assert {"scene", "method", "variant", "ratio", "metric", "mean", "ci_low", "ci_high", "n",
            "n_near_identical", "delta", "reference"} <= set(csv.columns)
    assert len(csv) == len(csv.drop_duplicates(["scene", "method", "variant", "ratio", "metric"]))
    assert not csv.columns.str.startswith("Unnamed").any()


def test_comparison_takes_new_metric_columns_from_the_registry(monkeypatch):
    from harness.metrics.builtin import psnr_pair
    from harness.metrics.registry import METRICS, register_metric

    monkeypatch.setattr(METRICS, "_entries", dict(METRICS._entries))  # registrations undone after the test
    db = dict(compute=psnr_pair, higher_is_better=True, unit="dB", cost="psnr", family="test", digits=2)
    register_metric("t_psnr", label="T-PSNR", **db)
    register_metric("t_psnr_om", label="OM-T-PSNR", masks="t_psnr", **db)
    df = _rows()
    df["t_psnr_om"], df["t_psnr"] = df["psnr"] - 1.0, df["psnr"]
    metrics = list(dict.fromkeys(_t("comparison", df).tidy["metric"]))
    assert metrics.index("t_psnr_om") == metrics.index("t_psnr") + 1  # OM beside full-frame


def test_ablation_marks_best_per_row_and_compares_with_the_full_method():
    t = _t("ablation")
    row = t.disp.loc[("scene A", "PSNR (↑)")]
    assert row[("With Descriptors", "Beta")] == "**28.00**"
    assert row[("No Descriptors", "No Beta")] == "20.00"
    assert t.disp.loc[("scene A", "LPIPS (↓)"), ("With Descriptors", "Beta")].startswith("**")
    nb = _cell(t.tidy, method="betadesc-nodesc-nobeta", metric="psnr")
    assert nb["reference"] == "betadesc[default]" and nb["delta"] == pytest.approx(-8.0)
    assert nb["ci_low"] == nb["ci_high"] == pytest.approx(-8.0)  # two identical differences
    assert t.warnings == []


def test_ablation_that_cannot_be_made_says_which_variants_are_missing():
    df = _rows()
    df = df[~((df["ratio"] - 0.2).abs() < 1e-9)]
    t = _t("ablation", df)
    assert isinstance(t, Missing)
    assert "missing betadesc-nodesc-nobeta, betadesc-nodesc, betadesc-nobeta at 20%" in t.reason
    ran = sorted(set(df.loc[df["method"].str.startswith("betadesc-"), "ratio"]))
    assert f"they ran at {', '.join(f'{100 * r:g}%' for r in ran)}" in t.reason
    # the full method alone is no ablation: a missing table, not a one-column one with a warning
    alone = _t("ablation", _rows()[lambda d: ~d["method"].str.startswith("betadesc-")])
    assert isinstance(alone, Missing) and "no ablation variant measured at 20%" in alone.reason
    part = _t("ablation", _rows()[lambda d: d["method"] != "betadesc-nobeta"])
    assert part.warnings == ["ablation: missing betadesc-nobeta at 20%"]


def test_keep_table_per_scene_with_paired_intervals_and_the_papers_sign():
    t = _t("keep")
    # prune 30%: no-desc 24, 24 vs with desc 25, 27 -> Δ = no − with = −1, −3: mean −2, t interval −2 ± 12.71
    row = _cell(t.tidy, scene="a", method="betadesc-nodesc", ratio=0.3, metric="psnr")
    assert row["delta"] == pytest.approx(-2.0) and row["n_pairs"] == 2
    assert (row["ci_low"], row["ci_high"]) == (pytest.approx(-2 - 12.7062047), pytest.approx(-2 + 12.7062047))
    assert _cell(t.tidy, scene="a", method="betadesc-nodesc", ratio=0.7, metric="psnr")["delta"] == pytest.approx(0.0)
    full = _cell(t.tidy, scene="a", method="betadesc", ratio=0.3, metric="psnr")
    assert full["mean"] == pytest.approx(26.0) and np.isnan(full["delta"])  # Δ lives on the no-descriptor side
    assert full["std"] == pytest.approx(math.sqrt(2.0))  # sample std (ddof = 1) of 25, 27, beside the mean
    # scene b has only betadesc at keep 0.7: it enters neither the table nor the pooled means
    assert "b" not in set(t.tidy["scene"])
    assert _cell(t.tidy, scene="*", method="betadesc", ratio=0.3, metric="psnr")["mean"] == pytest.approx(26.0)
    assert any("n = 2 paired views" in n for n in t.notes)


def test_per_scene_gain_sensitivity_and_runtime():
    t = build_tables(_rows(), ["per_scene", "sensitivity", "runtime"])
    g = t["per_scene"].tidy
    assert _cell(g, scene="a", ratio=0.3, metric="psnr")["delta"] == pytest.approx(2.0)
    assert _cell(g, scene="a", ratio=0.7, metric="psnr")["delta"] == pytest.approx(0.0)
    sens = t["sensitivity"]
    assert "keep 0.7" in sens.notes[0] and "scene A 2.50 dB" in sens.notes[-1]
    assert list(dict.fromkeys(sens.tidy["variant"])) == ["default", "preset=flat", "voxel=0.02"]
    assert _cell(sens.tidy, scene="a", variant="default", metric="psnr")["mean"] == pytest.approx(26.0)
    flat = _cell(sens.tidy, scene="a", variant="preset=flat", metric="psnr")
    assert flat["delta"] == pytest.approx(24.0 - 25.0) and flat["n_pairs"] == 1  # paired with view v0 only
    assert "b" not in set(sens.tidy["scene"])  # measured by the default variant only
    rt = t["runtime"]
    assert rt.disp.loc["scene A", "desc. overhead (s)"] == "0.50"
    assert set(rt.tidy.columns) >= {"scene", "method", "score_s", "score_s_std", "frames"}
    assert rt.caption.startswith("n = 1 frame(s) per scene")


def test_runtime_overhead_percentage_needs_a_denominator_of_a_second():
    """Issue 16: '23264.4 %' from a 0.01 s denominator."""
    df = _rows()
    assert _t("runtime", df).disp.loc["scene A", "desc. overhead (%)"] == "33.3"  # 0.5 / 1.5 s
    df.loc[df["method"] == "betadesc-nodesc", "score_s"] = 0.01
    t = _t("runtime", df)
    assert t.disp.loc["scene A", "desc. overhead (%)"] == "–"
    assert t.disp.loc["scene A", "desc. overhead (s)"] == "1.99"
    assert any("under 1 s" in n for n in t.notes)


def test_versus_pools_scenes_and_counts_verdicts():
    t = _t("versus", reference="betadesc-nodesc")
    row = _cell(t.tidy, scene="*", method="betadesc", variant="default", ratio=0.3, metric="psnr")
    # differences 1 and 3 dB on n = 2 views: the t interval 2 ± 12.71 includes 0 (a percentile
    # bootstrap would have said [1, 3], "better", from two views)
    assert row["delta"] == pytest.approx(2.0) and row["n_pairs"] == 2 and row["verdict"] == "unclear"
    assert (row["ci_low"], row["ci_high"]) == (pytest.approx(2 - 12.7062047), pytest.approx(2 + 12.7062047))
    psnr = dict(t.sections)["PSNR (↑)"]
    assert psnr.loc[("BetaDescPrune", "30%"), "better / worse / unclear"] == "0 / 0 / 1"
    assert psnr.loc[("BetaDescPrune", "20%"), "better / worse / unclear"] == "1 / 0 / 0"  # 2, 2: zero width
    assert "Student-t" in t.caption and "n = " in t.caption  # the caption states n and the interval
    assert isinstance(_t("versus", reference="nope"), Missing)


def test_files_and_tables_command_regenerates_without_cache(tmp_path, monkeypatch):
    df = _rows()
    write_results(df, tmp_path)
    assert read_results(tmp_path)["psnr"].isna().sum() == 1
    monkeypatch.setenv("HARNESS_CACHE", str(tmp_path / "no-cache-used"))
    assert main(["tables", str(tmp_path), "--plots", "curves", "--tables", "comparison", "ablation"]) == 0
    tex = (tmp_path / "tables" / "comparison.tex").read_text()
    assert r"\multicolumn{3}{c|}{Low}" not in tex and r"\multicolumn{3}{c|}{LightGSPrune}" in tex
    assert r"\multirow{5}{*}{scene A}" in tex and "PSNR ($\\uparrow$)" in tex  # 3 metrics, splats, bytes
    md = (tmp_path / "tables" / "ablation.md").read_text()
    assert "| scene A | 20.00 (Δ -8.00 [-8.00, -8.00]) |" in md
    assert (tmp_path / "plots" / f"curves_{file_name('scene A')}.png").stat().st_size > 1000
    assert not (tmp_path / "no-cache-used" / "stages").exists()


def test_tables_command_rejects_a_folder_without_results(tmp_path, capsys):
    assert main(["tables", str(tmp_path)]) == 2
    assert "no results.parquet" in capsys.readouterr().err


def test_csv_round_trip_keeps_inf(tmp_path):
    df = _rows()
    write_results(df, tmp_path)
    (tmp_path / "results.parquet").unlink()
    back = read_results(tmp_path)
    assert np.isinf(back["psnr"]).sum() == np.isinf(df["psnr"]).sum() == 3
    write_tables(back, tmp_path, ["comparison"])
    assert (tmp_path / "tables" / "comparison.csv").exists()


def test_tables_command_says_why_a_table_is_missing_and_exits_2(tmp_path, capsys):
    """Issue 16: `harness tables --tables ablation` exited 0 and wrote nothing."""
    df = _rows()
    write_results(df[~((df["ratio"] - 0.2).abs() < 1e-9)], tmp_path)
    (tmp_path / "tables").mkdir()
    (tmp_path / "tables" / "ablation.md").write_text("stale")
    assert main(["tables", str(tmp_path), "--tables", "ablation", "comparison", "--plots"]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if "not written" in ln]
    assert len(err) == 1 and err[0].startswith("harness: table ablation not written: no ablation variant measured")
    assert not (tmp_path / "tables" / "ablation.md").exists()  # no stale table beside the new ones
    assert (tmp_path / "tables" / "comparison.md").exists()


def test_confsplat_below_its_own_iterations_is_labelled_a_lower_bound(tmp_path):
    """ConfSplat trained for fewer iterations than its default (600) reads "lower bound (N iterations)"
    in every table; at its defaults it reads plainly."""
    import json as _json

    from harness.report import catalog
    from harness.report.outputs import publish

    df = _rows()
    df.loc[df["method"] == "lightgs", "method"] = "confsplat"
    df.loc[df["method"] == "confsplat", "params"] = _json.dumps({"iterations": 100})
    publish(tmp_path, df, {}, tables=["comparison"], plots=[])
    assert "ConfSplatPrune — lower bound (100 iterations)" in (tmp_path / "tables" / "comparison.md").read_text()
    assert "ConfSplatPrune — lower bound (100 iterations)" in (tmp_path / "report.html").read_text()
    df.loc[df["method"] == "confsplat", "params"] = _json.dumps({"iterations": 600})
    publish(tmp_path, df, {}, tables=["comparison"], plots=[])
    text = (tmp_path / "tables" / "comparison.md").read_text()
    assert "ConfSplatPrune" in text and "lower bound" not in text
    assert catalog.method_label("confsplat") == "ConfSplatPrune"  # no note outside a report build


def test_every_written_table_has_a_caption_with_n_and_the_interval(tmp_path):
    """A table whose builder gives no caption (e.g. a plugin's) gets one from its tidy rows."""
    from harness.report.tabledata import Table
    from harness.report.tables import with_caption

    w = write_tables(_rows(), tmp_path, ["comparison", "keep", "sensitivity", "runtime", "per_scene", "versus"])
    made = {k: b for k, b in w.built.items() if not isinstance(b.table, Missing)}
    assert len(made) == 5  # versus: no `random` in these rows
    for key, b in made.items():
        assert b.table.caption.startswith("n = "), key
    tidy = pd.DataFrame({"n": [2, 4], "ci_low": [0.1, 0.2], "ci_high": [0.3, 0.4]})
    t = with_caption(Table(pd.DataFrame(), [], tidy))
    assert t.caption.startswith("n = 2–4 per cell; intervals: ") and "Student-t" in t.caption
    assert with_caption(Table(pd.DataFrame(), [], pd.DataFrame({"x": [1]}))).caption == "no interval"
