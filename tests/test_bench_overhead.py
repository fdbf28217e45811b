"""`harness bench methods --overhead` (the runtime claim's benchmark) and `harness bench reading
directions`'s report, on small scenes."""

from __future__ import annotations

import numpy as np
import pytest

from harness.benchmarks import methods as bm
from harness.io.scenes import write_scene
from tests.scene_factory import random_scene


def test_overhead_times_both_methods_end_to_end_on_one_thread(tmp_path):
    path = tmp_path / "s.ply"
    write_scene(random_scene(3000, sh_degree=1, seed=2), path)
    out = bm.overhead([str(path)], repeats=3)
    (row,) = out["scenes"]
    assert out["threads"] == 1 and out["methods"] == ["betadesc", "betadesc-nodesc"] and row["splats"] == 3000
    assert out["pools"]["numba"] == 1 and out["pools"].get("torch", 1) == 1
    assert all(p.endswith(": 1") for p in out["pools"]["blas"])  # threadpoolctl: every BLAS/OpenMP pool at one
    assert len(row["overhead_pct"]) == 3 and all(len(row[k]) == 3 for k in ("full_cpu", "nodesc_cpu", "full_wall"))
    want = [100 * (f - n) / n for f, n in zip(row["full_cpu"], row["nodesc_cpu"])]
    np.testing.assert_allclose(row["overhead_pct"], want)
    np.testing.assert_allclose(row["added_s"], np.subtract(row["full_cpu"], row["nodesc_cpu"]))
    for key in ("overhead", "added"):
        lo, hi = row[f"{key}_ci"]
        assert lo <= row[f"{key}_mean"] <= hi
    for m in out["methods"]:  # every stage of the prune was timed, and they add up to the whole
        stages = row["stages_cpu_s"][m]
        assert set(stages) == {"read", "score", "select", "write"} and all(v >= 0 for v in stages.values())
        assert sum(stages.values()) == pytest.approx(np.mean(row[f"{'full' if m == 'betadesc' else 'nodesc'}_cpu"]))
    assert row["params"]["betadesc-nodesc"]["nodesc_def"] == "splat-params"  # the faithful ablation, not opacity
    assert row["params"]["betadesc"]["reading"] == "paper-literal"
    md = bm._overhead_markdown(out)
    assert "| s.ply |" not in md and str(path) in md and "overhead %" in md and "read, score, select" in md


def test_the_child_process_has_every_pool_pinned_before_import():
    from harness.benchmarks import _overhead as oh

    assert {"OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"} <= set(oh.ONE_THREAD)
    assert set(oh.ONE_THREAD.values()) == {"1"}


def test_a_baseline_far_from_the_papers_gets_a_note():
    from harness.benchmarks._overhead import baseline_note

    assert baseline_note([{"nodesc_cpu": [2.0, 3.0]}]) == ""  # 2.5 s: within 5× of 6.78 s
    fast = baseline_note([{"nodesc_cpu": [0.3, 0.3]}, {"nodesc_cpu": [0.5, 0.5]}])
    assert "0.40 CPU-s" in fast and "17× faster" in fast and "6.78" in fast
    assert "slower" in baseline_note([{"nodesc_cpu": [40.0]}])


def test_overhead_needs_two_repeats(capsys):
    from harness.cli import main

    assert main(["bench", "methods", "--overhead", "--repeats", "1"]) == 2
    assert "--repeats" in capsys.readouterr().err


def test_directions_report_marks_each_reading():
    from harness.study.bench.reading import directions_markdown

    rows = [{"scene": "x", "statistic": "s", "reading": "dims-var", "rho_geo": 0.1, "rho_app": -0.9,
             "rho_coherence": 0.0, "preserves": False},
            {"scene": "x", "statistic": "u", "reading": "dispersion", "rho_geo": -0.4, "rho_app": 0.2,
             "rho_coherence": -0.8, "preserves": True}]
    md = directions_markdown(rows, ["x"])
    assert "| s | `dims-var` | -0.90 R |" in md
    assert "| u | `dispersion` | -0.40 (C -0.80) **P** |" in md


@pytest.mark.parametrize("arg", ["--n", "--reps"])
def test_intervals_bench_rejects_bad_sizes(arg, capsys):
    from harness.cli import main

    assert main(["bench", "intervals", arg, "1" if arg == "--n" else "0"]) == 2
