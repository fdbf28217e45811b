"""`harness bench executors`: the ratios it reports, on hand-made wall times."""

from __future__ import annotations

import pytest

from harness.benchmarks.executors import summarise


def test_overhead_and_speedup_from_medians():
    walls = {("local", 1): [60.0, 62.0, 70.0], ("local", 2): [33.0], ("ray", 1): [66.0], ("ray", 2): [36.3]}
    s = summarise(walls)
    assert s["ray_overhead_1"] == pytest.approx(66.0 / 62.0 - 1)  # median of the local-1 runs
    assert s["ray_overhead_2"] == pytest.approx(0.1)
    assert s["speedup_local"] == pytest.approx(62.0 / 33.0)
    assert s["speedup_ray"] == pytest.approx(66.0 / 36.3)


def test_missing_variants_give_no_ratio():
    assert summarise({("local", 1): [10.0], ("ray", 2): [5.0]}) == {}
