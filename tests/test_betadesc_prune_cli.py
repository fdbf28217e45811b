"""`harness prune`: exact counts, output = input minus rows, JSON report, scores file, bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from harness.cli import main
from harness.io.scenes import load_scene, write_scene
from methods import PruneContext, get_pruner
from tests.scene_factory import random_scene

N = 301  # odd, so round(r·N) exercises rounding


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("prune") / "in.ply"
    write_scene(random_scene(N, sh_degree=3, seed=31, extra=True), path)
    return path


def _prune(capsys, *argv) -> tuple[int, str, str]:
    status = main(["prune", *map(str, argv)])
    out = capsys.readouterr()
    return status, out.out, out.err


@pytest.mark.parametrize("ratio", [0.0, 0.1, 0.3, 0.7, 1.0])
def test_exact_counts_and_rows_for_ratios(scene_file, tmp_path, capsys, ratio):
    out = tmp_path / "out.ply"
    scores_path = tmp_path / "s.npy"
    status, text, _ = _prune(capsys, scene_file, out, "--ratio", ratio, "--json", "--scores", scores_path)
    assert status == 0
    report = json.loads(text)
    removed = round(ratio * N)
    assert report["splats_in"] == N and report["splats_out"] == N - removed
    assert report["tau_quantile"] == removed / N
    assert {"read", "score", "select", "write"} <= set(report["seconds"])
    scene = load_scene(scene_file)
    scores = np.load(scores_path)
    expect = get_pruner("betadesc").score(scene, PruneContext())
    np.testing.assert_array_equal(scores, expect)
    order = np.argsort(expect, kind="stable")
    keep = np.ones(N, bool)
    keep[order[:removed]] = False
    assert (report["tau"] is None) if removed == 0 else report["tau"] == expect[order[removed - 1]]
    pruned = load_scene(out)
    kept = scene.subset(keep)
    assert len(pruned) == N - removed
    for field in ("means", "scales_log", "quats", "opacity_logit", "sh_dc", "sh_rest"):
        np.testing.assert_array_equal(getattr(pruned, field), getattr(kept, field))
    assert list(pruned.extra) == ["nx", "ny", "nz"]
    for k in pruned.extra:
        np.testing.assert_array_equal(pruned.extra[k], kept.extra[k])


@pytest.mark.parametrize("keep", [0.7, 0.5, 0.3])
@pytest.mark.parametrize("method", ["betadesc-nodesc", "betadesc-nobeta"])
def test_keep_fractions(scene_file, tmp_path, capsys, keep, method):
    out = tmp_path / "k.ply"
    status, text, _ = _prune(capsys, scene_file, out, "--keep", keep, "--method", method, "--json")
    assert status == 0
    assert json.loads(text)["splats_out"] == N - round((1 - keep) * N) == len(load_scene(out))


def test_options_reach_the_pruner_and_text_report(scene_file, tmp_path, capsys):
    out = tmp_path / "o.ply"
    sp = tmp_path / "o.npy"
    status, text, _ = _prune(capsys, scene_file, out, "--ratio", 0.2, "--preset", "flat", "--voxel", 0.02,
                             "--score", "lcb", "--gamma", 0.5, "--scores", sp)
    assert status == 0 and f"{N:,} -> {N - round(0.2 * N):,} splats" in text and "tau" in text
    params = {"preset": "flat", "voxel": 0.02, "score": "lcb", "gamma": 0.5}
    expect = get_pruner("betadesc").score(load_scene(scene_file), PruneContext(params=params))
    np.testing.assert_array_equal(np.load(sp), expect)


@pytest.mark.parametrize("argv, message", [
    (["--ratio", "1.5"], "--ratio"),
    (["--keep", "-0.1"], "--keep"),
    (["--ratio", "nan"], "--ratio"),
    (["--ratio", "0.3", "--method", "nosuch"], "unknown pruner"),
    (["--ratio", "0.3", "--method", "random", "--param", "preset=flat"], "--param preset: method 'random': no such "
                                                                          "parameter"),
    (["--ratio", "0.3", "--score", "mean"], "--score: method 'betadesc': 'mean' is not one of ucb, lcb"),
    (["--ratio", "0.3", "--preset", "heavy"], "'heavy' is not one of baseline, flat"),
    (["--ratio", "0.3", "--voxel", "0"], "--voxel: method 'betadesc': 0.0 is not > 0"),
    (["--ratio", "0.3", "--voxel", "-0.5"], "voxel"),
    (["--ratio", "0.3", "--voxel", "inf"], "--voxel: method 'betadesc': expected a finite number"),
    (["--ratio", "0.3", "--gamma", "nan"], "--gamma: method 'betadesc': expected a finite number"),
    (["--ratio", "0.3", "--param", "gamma"], "--param: expected NAME=VALUE"),
    (["--ratio", "0.3", "--param", "nope=1"], "--param nope: method 'betadesc': no such parameter"),
    (["--ratio", "0.3", "--max-nn", "2.5"], "--max-nn: method 'betadesc': expected int >= 1, got '2.5'"),
    (["--ratio", "0.3", "--method", "lightgs"], "--cameras: 'lightgs' needs training cameras; none were given"),
])
def test_bad_arguments_exit_2_without_output(scene_file, tmp_path, capsys, argv, message):
    out = tmp_path / "bad.ply"
    status, _, err = _prune(capsys, scene_file, out, *argv)
    assert status == 2 and message in err and err.startswith("harness: ") and len(err.splitlines()) == 1
    assert not out.exists()


def test_bad_input_files_exit_2_without_output(tmp_path, capsys):
    truncated = tmp_path / "t.splat"
    truncated.write_bytes(b"\0" * 45)
    for src, dst in ((tmp_path / "missing.ply", tmp_path / "a.ply"), (truncated, tmp_path / "b.ply")):
        status, _, err = _prune(capsys, src, dst, "--ratio", "0.3")
        assert status == 2 and err.startswith("harness: ")
        assert not dst.exists()
    status, _, err = _prune(capsys, truncated, tmp_path / "c.txt", "--ratio", "0.3")
    assert status == 2 and ".ply" in err
    good = tmp_path / "good.ply"
    write_scene(random_scene(10, seed=1), good)
    status, _, err = _prune(capsys, good, tmp_path / "d.ply", "--ratio", "0.3", "--scores", tmp_path / "no" / "s.npy")
    assert status == 2 and "output folder does not exist" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.ply", "t.splat"]


def test_header_comments_are_kept(tmp_path, capsys):
    """Pruned = input minus rows: the input's header comments (e.g. embedded cameras) survive."""
    from harness.io.ply import read_ply_header

    src = tmp_path / "in.ply"
    write_scene(random_scene(40, 1, seed=2), src, comments=['camera {"name": "c0"}', "made by a test"])
    assert main(["prune", str(src), str(tmp_path / "out.ply"), "--ratio", "0.25"]) == 0
    assert read_ply_header(tmp_path / "out.ply").comments == ['camera {"name": "c0"}', "made by a test"]


@pytest.mark.slow
def test_warmup_leaves_nothing_to_compile(tmp_path):
    """After `python -m methods.warmup` (run by setup.sh), scoring a real scene compiles no numba
    kernel: the first `harness prune` of a fresh install costs what the second does."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "PYTHONPATH": str(Path(__file__).parents[1])}
    subprocess.run([sys.executable, "-m", "methods.warmup"], env=env, check=True, capture_output=True, timeout=1800)
    probe = (
        "from numba.core import event\n"
        "names = []\n"
        "class L(event.Listener):\n"
        "    def on_start(self, ev): names.append(ev.data['dispatcher'].py_func.__name__)\n"
        "    def on_end(self, ev): pass\n"
        "event.register('numba:compile', L())\n"
        "from methods.warmup import synthetic_scene\n"
        "from methods.registry import get_pruner, PruneContext\n"
        "for deg, n in ((0, 7001), (3, 4003)):\n"
        "    s = synthetic_scene(n, deg, seed=5)\n"
        "    for m in ('betadesc', 'betadesc-nodesc', 'betadesc-nobeta', 'betadesc-nodesc-nobeta'):\n"
        "        get_pruner(m).score(s, PruneContext())\n"
        "print(names)\n")
    out = subprocess.run([sys.executable, "-c", probe], env=env, check=True, capture_output=True, text=True,
                         timeout=600).stdout
    assert out.strip() == "[]", f"compiled after the warm-up: {out}"
