"""`harness bench calibrate --check RUN_DIR`: an estimate set against what a finished run measured —
the measured column is the run's own record and rows, the estimate is `plan --estimate`'s."""

from __future__ import annotations

import json

import pytest
import yaml

import harness
from harness.cli import main
from tests import runner_fakes as fakes
from tests.gl_support import require_gl


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    require_gl()
    tmp = tmp_path_factory.mktemp("check")
    scenes = fakes.write_two_scenes(tmp)
    doc = {"name": "check", "workers": 1, "protocols": ["rig", "shifted"],
           "protocol": {"longest_side": 24, "metrics": ["psnr"], "n_train": 2, "n_test": 2},
           "ratios": [0.1, 0.3], "scenes": [{"name": k, "source": v} for k, v in scenes.items()],
           "methods": ["opacity", "random"], "tables": [], "plots": []}
    config = tmp / "c.yaml"
    config.write_text(yaml.safe_dump(doc))
    harness.evaluate(config, out=tmp / "run", cache=str(tmp / "cache"))
    return tmp / "run"


def test_the_measured_column_is_the_runs_own(run_dir, tmp_path, capsys):
    from harness.report.results import read_results
    from harness.run.config import parse_config
    from harness.run.estimate import estimate, scene_info
    from harness.run.scene_sizes import Assumptions
    from harness.run.unit_costs import from_bench

    bench = tmp_path / "bench"  # no benchmark files: the built-in units
    bench.mkdir()
    assert main(["bench", "calibrate", "--check", str(run_dir), "--bench", str(bench), "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    doc = json.loads((tmp_path / "calibrate-check-check.json").read_text())
    rows = {r["what"]: r for r in doc["rows"]}
    record = json.loads((run_dir / "run.json").read_text())
    assert rows["CPU seconds (cold run)"]["measured"] == record["cpu_seconds"]
    assert rows["wall seconds (cold run)"]["measured"] == record["stage_seconds"]["total"]
    df = read_results(run_dir)
    for proto in ("rig", "shifted"):
        sub = df[df["protocol"] == proto]
        views = sub.drop_duplicates(["scene", "frame", "view"])
        want = sub["render_s"].sum() + sub["metrics_s"].sum() + views["render_ref_s"].sum()
        assert rows[f"task seconds: {proto} views"]["measured"] == pytest.approx(want)
    config = parse_config(record["config"], "run.json")
    est = estimate(config, [scene_info(s, config, Assumptions()) for s in config.scenes], from_bench(bench))
    assert rows["CPU seconds (cold run)"]["estimate"] == pytest.approx(est.cpu_s(1))
    assert rows["wall seconds (cold run)"]["estimate"] == pytest.approx(est.wall_s(1, 0.9))
    for r in doc["rows"]:
        assert r["ratio"] == pytest.approx(r["estimate"] / r["measured"])
        assert r["within"] == (1 / 1.2 <= r["ratio"] <= 1.2)
    assert f"{sum(r['within'] for r in doc['rows'])} of {len(doc['rows'])} within 20 %" in out
    assert doc["cache_hits"] == 0 and "was not cold" not in out


def test_a_folder_that_is_not_a_run_is_one_line(tmp_path, capsys):
    assert main(["bench", "calibrate", "--check", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("harness: ") and err.count("\n") == 1, err
