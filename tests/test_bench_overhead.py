"""`harness bench methods --overhead` (the runtime claim's benchmark) and `harness bench reading
directions`'s report, on small scenes."""

from __future__ import annotations

import numpy as np
import pytest

from harness.benchmarks import methods as bm
from harness.io.scenes import write_scene
from tests.scene_factory import random_scene


def test_overhead_times_both_methods_single_threaded(tmp_path):
    import numba

    path = tmp_path / "s.ply"
    write_scene(random_scene(3000, sh_degree=1, seed=2), path)
    before = numba.get_num_threads()
    out = bm.overhead([str(path)], repeats=3)
    assert numba.get_num_threads() == before  # restored
    (row,) = out["scenes"]
    assert out["threads"] == 1 and out["methods"] == ["betadesc", "betadesc-nodesc"] and row["splats"] == 3000
    assert len(row["overhead_pct"]) == 3 and all(len(row[k]) == 3 for k in ("full_cpu", "nodesc_cpu", "full_wall"))
    want = [100 * (f - n) / n for f, n in zip(row["full_cpu"], row["nodesc_cpu"])]
    np.testing.assert_allclose(row["overhead_pct"], want)
    lo, hi = row["overhead_ci"]
    assert lo <= row["overhead_mean"] <= hi
    assert row["params"]["betadesc-nodesc"]["nodesc_def"] == "splat-params"  # the faithful ablation, not opacity
    md = bm._overhead_markdown(out)
    assert "| s.ply |" not in md and str(path) in md and "overhead %" in md


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
