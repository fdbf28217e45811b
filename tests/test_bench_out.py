"""Every `harness bench` takes --out; by default nothing under the tracked results/ is rewritten
(issue 23: `harness bench read` overwrote the committed results/bench/read.json and .md)."""

from __future__ import annotations

import pytest

from harness.benchmarks import _common
from harness.cli import main
from harness.commands.bench import benchmarks
from harness.core.paths import results_dir
from harness.io.scenes import write_scene
from tests.scene_factory import random_scene


def test_every_benchmark_takes_out(capsys):
    for entry in benchmarks():
        with pytest.raises(SystemExit):
            main(["bench", entry.name, "--help"])
        assert "--out DIR" in capsys.readouterr().out, entry.name


def test_default_is_outside_the_tracked_tree_and_a_tracked_folder_is_named(tmp_path, monkeypatch, capsys):
    scene = tmp_path / "s.ply"
    write_scene(random_scene(200, seed=1), scene)
    monkeypatch.chdir(tmp_path)
    assert main(["bench", "read", "--scene", str(scene), "--repeats", "1"]) == 0
    out = capsys.readouterr().out
    assert "bench: wrote runs/bench/read.json and .md" in out and "committed" not in out
    assert (tmp_path / "runs" / "bench" / "read.md").is_file()
    assert main(["bench", "read", "--scene", str(scene), "--repeats", "1", "--out", str(tmp_path / "mine")]) == 0
    assert (tmp_path / "mine" / "read.json").is_file()
    assert "committed results" in _common.tracked_note(results_dir() / "bench")
    assert _common.tracked_note(tmp_path / "mine") == ""


def test_out_that_is_a_file_is_one_line_before_any_work(tmp_path, capsys):
    (tmp_path / "f").write_text("x")
    assert main(["bench", "read", "--scene", str(tmp_path / "nope.ply"), "--out", str(tmp_path / "f")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(tmp_path / "f") in err
