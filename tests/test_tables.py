"""Tables from tidy results: means by hand, inf handling, the paper's layouts, and `harness tables`."""

from __future__ import annotations

import math

import numpy as np
import pytest

from harness.cli import main
from harness.report.results import read_results, to_frame, write_results
from harness.report.summary import summarise
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


def test_comparison_layout_and_values():
    num, disp, notes = build_tables(_rows(), ["comparison"])["comparison"]
    assert list(num.columns.get_level_values("method").unique()) == ["LightGSPrune", "BetaDescPrune"]
    assert list(num.columns.get_level_values("level")[:3]) == ["Low", "Mid", "High"]
    psnr = num.loc[("scene A", "PSNR (↑)")]
    assert psnr[("Our Method", "BetaDescPrune", "Low")] == pytest.approx(31.0)
    assert psnr[("Our Method", "BetaDescPrune", "High")] == pytest.approx(26.0)
    assert disp.loc[("scene A", "PSNR (↑)"), ("Camera-Aware Methods", "LightGSPrune", "Mid")] == "inf"
    assert any("exclude 3 identical" in n for n in notes)


def test_ablation_marks_best_per_row():
    _, disp, _ = build_tables(_rows(), ["ablation"])["ablation"]
    row = disp.loc[("scene A", "PSNR (↑)")]
    assert row[("With Descriptors", "Beta")] == "**28.00**"
    assert row[("No Descriptors", "No Beta")] == "20.00"
    assert disp.loc[("scene A", "LPIPS (↓)"), ("With Descriptors", "Beta")].startswith("**")


def test_keep_table_delta_uses_the_papers_sign():
    num, _, _ = build_tables(_rows(), ["keep"])["keep"]
    assert list(num.index) == ["30%", "50%", "70%"]
    # prune 30%: no-desc 24, with desc (25+27)/2 = 26 -> ΔPSNR = 24 - 26 = -2
    assert num.loc["30%", ("ΔPSNR", "(dB)")] == pytest.approx(-2.0)
    assert num.loc["70%", ("ΔPSNR", "(dB)")] == pytest.approx(0.0)


def test_per_scene_gain_and_sensitivity():
    t = build_tables(_rows(), ["per_scene", "sensitivity", "runtime"])
    gains = t["per_scene"][0]
    assert gains.loc["scene A", "prune 30%"] == pytest.approx(2.0)
    assert gains.loc["scene A", "prune 70%"] == pytest.approx(0.0)
    sens, _, notes = t["sensitivity"]
    assert list(sens.index.get_level_values("variant")) == ["default", "preset=flat", "voxel=0.02"]
    assert "(a)" in notes[0]
    assert sens.loc[("baseline", "default"), "PSNR (↑)"] == pytest.approx(26.0)
    rt = t["runtime"][0]
    assert rt.loc["scene A", "desc. overhead (s)"] == pytest.approx(0.5)


def test_files_and_tables_command_regenerates_without_cache(tmp_path, monkeypatch):
    df = _rows()
    write_results(df, tmp_path)
    assert read_results(tmp_path)["psnr"].isna().sum() == 1
    monkeypatch.setenv("HARNESS_CACHE", str(tmp_path / "no-cache-used"))
    assert main(["tables", str(tmp_path), "--plots", "curves"]) == 0
    tex = (tmp_path / "tables" / "comparison.tex").read_text()
    assert r"\multicolumn{3}{c|}{Low}" not in tex and r"\multicolumn{3}{c|}{LightGSPrune}" in tex
    assert r"\multirow{3}{*}{scene A}" in tex and "PSNR ($\\uparrow$)" in tex
    md = (tmp_path / "tables" / "ablation.md").read_text()
    assert "| scene A | PSNR (↑) |" in md
    assert (tmp_path / "plots" / "curves_scene_A.png").stat().st_size > 1000
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
