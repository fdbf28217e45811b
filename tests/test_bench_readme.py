"""results/bench/README.md's figures are the committed benchmark files' numbers, as printed there:
each checked figure is read from its file and formatted as the page prints it, and every benchmark
file the page names exists."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parent.parent / "results" / "bench"
PAGE = BENCH / "README.md"

#: (a phrase of the row, file, key path, format): the formatted value must appear in that row
FIGURES = [
    ("read bonsai-7k.splat", "read.json", "steps.read.seconds", "{:.2f} s"),
    ("read bonsai-7k.splat", "read.json", "steps.read.peak_alloc_mb", "{:.0f} MiB"),
    ("GL render, bonsai-7k", "render-bonsai-7k.json", "backends.gl.seconds_per_view", "{:.2f} s/view"),
    ("GL render, bonsai-7k", "render-bonsai-7k.json", "backends.reference.seconds_per_view", "rasterizer {:.1f} s"),
    ("LPIPS per extra pruned image", "metrics.json", "lpips_cached_per_pruned_s", "{:.2f} s vs"),
    ("LPIPS per extra pruned image", "metrics.json", "lpips_naive_pair_s", "vs {:.2f} s"),
    ("LPIPS per extra pruned image", "metrics.json", "ratio_cached_over_naive", "{:.2f}×"),
    ("our FPFH", "fpfh.json", "speedup_wall_median", "{:.2f}×"),
    ("our FPFH", "fpfh.json", "speedup_wall_best", "best {:.2f}×"),
    ("vs the default study's cold run", "calibrate-check-default.json", "rows.0.estimate", "CPU {:,.1f} vs"),
    ("vs the default study's cold run", "calibrate-check-default.json", "rows.0.measured", "vs {:,.1f} s"),
    ("vs the default study's cold run", "calibrate-check-default.json", "rows.0.ratio", "({:.2f}×)"),
    ("everyday commands as processes", "start.json", "ratios.harness score luigi -n 16.wall", "-n 16` {:.2f}×"),
    ("everyday commands as processes", "start.json", "ratios.harness render luigi.wall", "render luigi` {:.2f}×"),
    ("everyday commands as processes", "start.json", "ratios.harness compare.wall", "compare` {:.2f}×"),
    ("vs the default study's cold run", "calibrate-check-default.json", "rows.1.estimate", "wall {:,.1f} vs"),
    ("vs the default study's cold run", "calibrate-check-default.json", "rows.1.ratio", "({:.2f}×)"),
    ("vs the default study's cold run", "calibrate-check-default.json", "rows.2.ratio", "stages {:.2f}×"),
    ("vs the default study's cold run", "calibrate-check-default.json", "rows.3.ratio", "and {:.2f}×"),
    ("vs the default study's cold run", "calibrate-check-default.json", "rows.4.ratio", "scoring {:.2f}×"),
]


#: files the page names as not there yet, and why
NOT_YET = {"calibrate-cuda.json": "the page says a GPU session will commit it"}


def row(phrase: str) -> str:
    rows = [line for line in PAGE.read_text().splitlines() if line.startswith("|") and phrase in line]
    assert len(rows) == 1, f"{phrase!r}: {len(rows)} rows of results/bench/README.md"
    return rows[0]


def value(name: str, path: str):
    data = json.loads((BENCH / name).read_text())
    for key in path.split("."):
        data = data[int(key)] if isinstance(data, list) else data[key]
    return data


@pytest.mark.parametrize("phrase, name, path, fmt", FIGURES, ids=[f"{f[1]}:{f[2]}" for f in FIGURES])
def test_figure_is_the_file_s(phrase, name, path, fmt):
    printed = fmt.format(value(name, path))
    assert printed in row(phrase).replace("**", ""), f"{name} {path} = {printed!r}, not in the row of {phrase!r}"


def test_named_benchmark_files_exist():
    text = PAGE.read_text()
    named = set(re.findall(r"`(?:results/bench/)?([\w.*-]+\.(?:json|md|png))`", text))
    assert named, "the page names no benchmark file"
    missing = [n for n in named - set(NOT_YET) if not list(BENCH.glob(n))]
    assert not missing, f"results/bench/README.md names files that are not there: {missing}"
