"""`harness bench start`: each child's own peak memory and CPU, alternating rounds, one result file."""

from __future__ import annotations

import json
import sys

from harness.benchmarks.start import run_child
from harness.cli import main
from harness.core.paths import REPO_ROOT


def test_each_childs_own_peak_and_cpu(tmp_path):
    """wait4 reports the child's own rusage: a small child after a big one is small again (the
    RUSAGE_CHILDREN maximum would still say 300 MiB)."""
    big, _ = run_child([sys.executable, "-c", "b = bytearray(300 * 2**20); b[::4096] = b'x' * len(b[::4096])"],
                       tmp_path)
    small, out = run_child([sys.executable, "-c", "print('hi')"], tmp_path)
    assert big.peak_mib > 300 > 50 > small.peak_mib and out == "hi\n"
    spin, _ = run_child([sys.executable, "-c", "import time\nt = time.process_time()\nwhile time.process_time() - t "
                                               "< 0.3: pass"], tmp_path)
    assert spin.cpu_s >= 0.3 and spin.wall_s >= spin.cpu_s * 0.5


def test_a_round_against_another_checkout(tmp_path, capsys):
    out = tmp_path / "bench"
    assert main(["bench", "start", "--repeats", "2", "--only", "harness --help", "--against", str(REPO_ROOT),
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    payload = json.loads((out / "start.json").read_text())
    assert set(payload["trees"]) == {"this", "against", "-"} and payload["repeats"] == 2
    row = payload["trees"]["this"]["harness --help"]
    assert len(row["wall_s"]["samples"]) == 2 and row["peak_mib"]["median"] > 0
    assert len(payload["trees"]["-"]["python -c 'import numpy'"]["wall_s"]["samples"]) == 2
    assert 0 < payload["ratios"]["harness --help"]["wall"] < 10
    assert "| `harness --help` |" in (out / "start.md").read_text() and "≤ 0.3 s" in text


def test_bad_arguments_are_one_line(tmp_path, capsys):
    for argv, phrase in ((["--against", str(tmp_path)], "--against: "), (["--only", "harness nope"], "--only: "),
                         (["--repeats", "0"], "--repeats: ")):
        assert main(["bench", "start", *argv, "--out", str(tmp_path / "o")]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"harness: {phrase}") and err.count("\n") == 1, err


def test_every_goal_is_said_met_or_missed_and_the_cached_rerun_is_set_beside_its_hits():
    """A command faster than its goal reads "met", a slower one "missed"; the cached rerun's note
    divides by the hits of its run."""
    from pathlib import Path

    from harness.benchmarks.start import BASELINE, CACHED_RUN, COMMANDS, Sample, markdown, summarise

    fast, slow = "harness compare --metrics psnr", "harness compare"
    samples = {"this": {fast: [Sample(0.2, 0.2, 100, 1.0)], slow: [Sample(4.0, 4.0, 900, 1.0)],
                        CACHED_RUN: [Sample(2.0, 1.5, 200, 1.0, hits=100)]},
               "-": {BASELINE: [Sample(0.1, 0.1, 25, 1.0)]}}
    md = markdown(summarise(samples, ["this"]), {"this": Path(".")}, 1)
    assert f"| `{fast}` |" in md and md.split(f"| `{fast}` |")[1].split("\n")[0].endswith("≤ 0.5 s: met |")
    assert "≤ 3 s: missed; ≤ 800 MiB: missed |" in md.split(f"| `{slow}` |")[1].split("\n")[0]
    assert "for 100 cache hits (20.0 ms a hit" in md
    assert all(goal_s or goal_mib or name in ("harness prune luigi", "harness prune bonsai-7k --reading v1")
               for name, (_, goal_s, goal_mib) in COMMANDS.items())


def test_the_inputs_are_two_1024_by_768_pngs_and_a_pruned_luigi(tmp_path):
    import numpy as np
    import pytest
    from PIL import Image

    from harness.benchmarks.start import make_inputs

    try:
        paths = make_inputs(tmp_path, REPO_ROOT)
    except RuntimeError as err:
        pytest.skip(f"luigi is not here (harness fetch): {err}")
    a, b = (np.asarray(Image.open(paths[k])) for k in ("A_PNG", "B_PNG"))
    assert a.shape == b.shape == (768, 1024, 3) and 0 < np.abs(a.astype(int) - b).mean() < 10
    assert paths["PRUNED"].stat().st_size > 0
