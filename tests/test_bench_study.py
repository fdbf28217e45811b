"""`harness bench study`: the figures it reports from its runs, its input checks, and one real (tiny)
study measured end to end."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from harness.benchmarks import study
from harness.core.errors import InputError


def _fake(cold_cpu: float, cached_cpu: float) -> dict:
    stages = {s: 0.0 for s in study.STAGES}
    cold = {"cpu_s": cold_cpu, "wall_s": 2 * cold_cpu, "stage_cpu_s": {**stages, "render_metrics": cold_cpu / 2},
            "outside_cpu_s": cold_cpu / 2}
    cached = {"cpu_s": cached_cpu, "wall_s": cached_cpu, "stage_cpu_s": stages, "outside_cpu_s": cached_cpu}
    return {"cold": cold, "cached": cached, "worker_startup_cpu_s": 1.0, "versions_cpu_s": 0.1,
            "per_image": {"images": 10, "render_metrics_cpu_s": cold_cpu / 20, "render_s": 0.1, "metrics_s": 0.2}}


def test_figures_are_medians_and_the_table_has_ratios():
    figs = {"this": study._figures([_fake(10, 2), _fake(30, 4), _fake(20, 3)]), "other": study._figures([_fake(40, 6)])}
    assert figs["this"]["cold CPU-s (whole run)"] == 20 and figs["this"]["cached rerun CPU-s (whole run)"] == 3
    assert figs["this"]["cold render_metrics CPU-s"] == 10 and figs["this"]["render+metrics CPU-s per image"] == 1
    md = study._markdown("c.yaml", 1, ["this", "other"], figs, 3, "note", "goal")
    assert "| cold CPU-s (whole run) | 20.0 | 40.0 | 0.50 |" in md
    assert "| cached rerun CPU-s (whole run) | 3.000 | 6.000 | 0.50 |" in md


def _args(tmp_path, **kw):
    base = dict(config_file=None, config="ctc_configs/ci.yaml", against=None, repeats=1, workers=1, timeout=60,
                out=str(tmp_path), device=None, check=None, scenes=None)
    return argparse.Namespace(**{**base, **kw})


@pytest.mark.parametrize("kw, match", [({"repeats": 0}, "--repeats"), ({"workers": 0}, "--workers"),
                                       ({"config": "nope.yaml"}, "no such config"),
                                       ({"against": "/tmp"}, "not a checkout"),
                                       ({"config_file": "ctc_configs/default.yaml"}, "two configs"),
                                       ({"device": "cpu", "repeats": 2}, "leave out --against"),
                                       ({"device": "tpu"}, "--device"),
                                       ({"device": "cpu", "check": "luigii"}, "no scene 'luigii'"),
                                       ({"device": "cpu", "scenes": "luigi", "check": "grape-small"},
                                        "among --scenes")])
def test_bad_arguments_are_one_line_errors(tmp_path, kw, match):
    with pytest.raises(InputError, match=match):
        study.run(_args(tmp_path, **kw))


@pytest.mark.slow
@pytest.mark.gl
@pytest.mark.weights
def test_a_tiny_study_end_to_end(tmp_path):
    from tests import runner_fakes as fakes

    scene = fakes.write_two_scenes(tmp_path)["s0"]
    config = tmp_path / "tiny.yaml"
    config.write_text(json.dumps({"name": "tiny", "protocol": {"longest_side": 32, "metrics": ["psnr"], "n_test": 1,
                                                                "n_train": 1}, "ratios": [0.5],
                                  "scenes": [{"name": "s0", "source": scene}], "methods": ["opacity"],
                                  "tables": [], "plots": []}))
    assert study.run(_args(tmp_path / "bench", config=str(config))) == 0
    res = json.loads((tmp_path / "bench" / "study-tiny.json").read_text())
    run = res["runs"]["this"][0]
    assert run["cold"]["cpu_s"] > run["cold"]["stage_cpu_s"]["render_metrics"] > 0
    assert run["cached"]["misses"] == 0 and run["cached"]["stage_cpu_s"]["render_metrics"] < 0.5
    assert res["tables_stable"] and Path(tmp_path / "bench" / "study-tiny.md").is_file()


def test_device_mode_subset_and_table_comparison(tmp_path):
    from harness.benchmarks import _study_device as sd

    doc = {"scenes": [{"name": "a"}, {"name": "b"}, "c"],
           "methods": ["opacity", {"name": "x", "scenes": ["b"]}, {"name": "y", "scenes": ["a", "b"], "keep": [0.7]}]}
    sub = sd.subset(doc, ["a"])
    assert sub["scenes"] == [{"name": "a"}] and sub["methods"] == ["opacity", {"name": "y", "scenes": ["a"],
                                                                                 "keep": [0.7]}]
    assert doc["methods"][2]["scenes"] == ["a", "b"]  # the input is not modified
    assert sd._last_digit("56.89 (Δ +16.84 [+8.57, +25.12])", "56.90 (Δ +16.84 [+8.56, +25.12])")
    assert not sd._last_digit("56.89", "56.91") and not sd._last_digit("0.5", "0.50")
    assert not sd._last_digit("a 1", "b 1")
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir(), b.mkdir()
    (a / "t.md").write_text("# T\n\n| k | v |\n|---|---|\n| x | 1.00 |\n| y | 2.00 |\n| z | 3.0 |\n")
    (b / "t.md").write_text("# T\n\n| k | v |\n|---|---|\n| x | 1.00 |\n| y | 2.01 |\n| z | 3.5 |\n")
    (a / "runtime.md").write_text("| s | 1 |\n")
    (b / "runtime.md").write_text("| s | 2 |\n")
    (a / "only.md").write_text("| s | 1 |\n")
    got = sd.compare_tables(a, b)
    assert (got["files"], got["cells"], got["last_digit"], got["more"]) == (2, 10, 1, 1)
    assert got["missing"] == ["only.md"]
    assert got["equal"] == 8 and got["differ"] == ["t.md: z: '3.0' vs '3.5'"]
    with sd.GpuMemory("cpu") as mem:
        pass
    assert mem.used_mib is None


@pytest.mark.slow
@pytest.mark.gl
def test_device_mode_end_to_end_on_the_cpu(tmp_path):
    """--device cpu: the study, then its subset on the device (here the CPU again) and on the CPU: every
    cell equal."""
    from tests import runner_fakes as fakes

    scenes = fakes.write_two_scenes(tmp_path)
    config = tmp_path / "tiny.yaml"
    config.write_text(json.dumps({"name": "tiny", "protocol": {"longest_side": 32, "metrics": ["psnr", "rgb_psnr"],
                                                                "n_test": 2, "n_train": 1}, "ratios": [0.3, 0.5],
                                  "scenes": [{"name": k, "source": v} for k, v in scenes.items()],
                                  "methods": ["opacity", "random"], "tables": ["comparison"], "plots": []}))
    assert study.run(_args(tmp_path / "bench", config=str(config), device="cpu")) == 0
    res = json.loads((tmp_path / "bench" / "study-tiny-cpu.json").read_text())
    assert res["study"]["images"] == 2 * 2 * 2 * 2 and res["study"]["gpu_memory_mib"] is None
    assert res["study"]["stage_wall_s"]["render_metrics"] > 0 and res["study"]["images_per_s"] > 0
    check = res["check"]
    assert check["scenes"] == ["s0"] and check["cpu"]["images"] == check["device"]["images"] == 2 * 2 * 2
    assert check["tables"]["cells"] > 0 and check["tables"]["equal"] == check["tables"]["cells"]
    md = (tmp_path / "bench" / "study-tiny-cpu.md").read_text()
    assert "## Check: the subset on s0" in md and "equal**" in md
