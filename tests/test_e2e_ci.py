"""End to end: `harness run ctc_configs/ci.yaml` on real scenes (GL, LPIPS), then a rerun that recomputes nothing."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from harness.io.datasets import scene_path
from harness.metrics.lpips_weights import weights_path

REPO = Path(__file__).resolve().parent.parent


@pytest.mark.slow
@pytest.mark.data
@pytest.mark.gl
@pytest.mark.weights
def test_ci_config_end_to_end(tmp_path):
    for name in ("grape-small", "luigi"):
        if not scene_path(name).exists():
            pytest.skip(f"{name} is absent ({scene_path(name)}); run `harness fetch`")
    if not weights_path().is_file():
        pytest.skip("LPIPS weights absent; run `harness fetch --weights`")
    cmd = [
        sys.executable,
        "-m",
        "harness",
        "run",
        str(REPO / "ctc_configs" / "ci.yaml"),
        "--out",
        str(tmp_path / "out"),
        "--cache",
        str(tmp_path / "cache"),
    ]
    first = subprocess.run(cmd, capture_output=True, text=True, timeout=900, check=False, env=os.environ.copy())
    if "GLUnavailable" in first.stdout + first.stderr:
        pytest.skip("no EGL context on this machine")
    assert first.returncode == 0, first.stdout + first.stderr
    df = pd.read_parquet(tmp_path / "out" / "results.parquet")
    assert (df["status"] == "ok").all() and set(df["scene"]) == {"grape-small", "luigi"}
    assert set(df["method"]) >= {"betadesc", "lightgs", "confsplat", "opacity", "random"}
    assert df["lpips"].between(0, 1).all() and (df["ssim"] <= 1).all()
    for name in ("comparison.md", "comparison.tex", "comparison.csv", "keep.md", "summary.csv", "ablation.md",
                 "versus.csv"):
        assert (tmp_path / "out" / "tables" / name).stat().st_size > 0
    assert "warning:" not in first.stdout  # every table and plot ci.yaml lists is made
    page = (tmp_path / "out" / "report.html").read_text()
    # one image comparison (slider) per scene × method × variant × ratio
    assert page.count("type='range' min='0'") == df.groupby(["scene", "method", "variant", "ratio"]).ngroups
    assert (tmp_path / "out" / "plots" / "figure1.png").exists()
    assert len(list((tmp_path / "out" / "contact_sheets").glob("*.png"))) == 2

    again = subprocess.run(cmd, capture_output=True, text=True, timeout=900, check=False)
    assert again.returncode == 0
    counts = json.loads((tmp_path / "out" / "run.json").read_text())["cache_counts"]
    # one metrics entry per (view, keep mask): methods that keep the same splats share it
    entries = len(list((tmp_path / "cache" / "metrics").rglob("*.json")))
    assert sum(c["misses"] for c in counts.values()) == 0 and counts["metrics"]["hits"] == entries <= len(df)
