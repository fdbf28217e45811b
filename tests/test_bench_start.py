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
