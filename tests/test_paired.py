"""Paired per-view differences, their bootstrap CI, and the pre-registered greedy reading selection."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import yaml

from harness.report import reading_search as rs
from harness.report.paired import bootstrap_ci, compare, paired_difference


def test_bootstrap_ci_hand_cases():
    mean, lo, hi = bootstrap_ci([2.0, 2.0, 2.0])
    assert (mean, lo, hi) == (2.0, 2.0, 2.0)  # no spread: every resample has mean 2
    d = np.array([0.0, 1.0])
    mean, lo, hi = bootstrap_ci(d, resamples=20_000)
    assert mean == 0.5 and lo == 0.0 and hi == 1.0  # resample means are 0, .5, 1 with P = ¼, ½, ¼
    assert bootstrap_ci(d, seed=3) == bootstrap_ci(d, seed=3)  # deterministic in the seed
    assert np.isnan(bootstrap_ci([])[0])


def test_bootstrap_ci_covers_a_known_mean():
    rng = np.random.default_rng(1)
    d = rng.normal(1.0, 1.0, 400)
    mean, lo, hi = bootstrap_ci(d)
    se = d.std() / np.sqrt(d.size)
    assert lo < mean < hi and (hi - lo) / 2 == pytest.approx(1.96 * se, rel=0.1)


def test_paired_difference_excludes_identical_views_and_pairs_by_view():
    cand = pd.Series({"a": 30.0, "b": 40.0, "c": np.inf, "d": 20.0, "e": 25.0})
    ref = pd.Series({"a": 29.0, "b": 38.0, "c": 50.0, "d": 120.0, "f": 10.0})
    p = paired_difference(cand, ref)
    assert (p.n, p.n_excluded) == (2, 2)  # a, b used; c (inf) and d (>= 100 dB) excluded; e, f unpaired
    assert p.mean == pytest.approx(1.5)
    p2 = paired_difference(cand, [ref, ref + 1.0])  # two references averaged per view
    assert p2.mean == pytest.approx(1.0)


def _rows(scene, method, params, psnrs, ratio=0.3, variant="default"):
    return [{"scene": scene, "method": method, "variant": variant, "params": json.dumps(params), "ratio": ratio,
             "view": f"v{i}", "status": "ok", "psnr": x} for i, x in enumerate(psnrs)]


def test_compare_selects_sides_by_params_subset():
    df = pd.DataFrame(_rows("s", "random", {}, [20, 21, 22])
                      + _rows("s", "betadesc", {"o_norm": "rank", "prior": 1.0}, [21, 23, 22], variant="x")
                      + _rows("s", "betadesc", {"o_norm": "minmax", "prior": 1.0}, [25, 25, 25], variant="y"))
    p = compare(df, scene="s", ratio=0.3, candidate={"method": "betadesc", "params": {"o_norm": "rank"}},
                reference={"method": "random"})
    assert p.mean == pytest.approx(1.0) and p.n == 3
    with pytest.raises(ValueError, match="several variants"):
        compare(df, scene="s", ratio=0.3, candidate={"method": "betadesc", "params": {"prior": 1.0}},
                reference={"method": "random"})


CONFIG = """
name: t
output: runs/t
ratios: [0.3]
scenes: [{name: s1}, {name: s2}]
methods:
  - random
  - {name: betadesc, variant: lit, params: {reading: paper-literal}, sweep: {o_norm: [rank, sigmoid]}}
  - {name: betadesc, variant: lit, params: {reading: paper-literal}, sweep: {prior: [2.0]}}
"""


def _fake_results(space, effect):
    """Rows for every reading the greedy walk can visit; PSNR = 20 + effect(params) + view noise."""
    rows = []
    rng = np.random.default_rng(0)
    noise = rng.normal(0, 0.05, 8)
    for s in space.scenes:
        rows += _rows(s, "random", {}, 20 + noise)
        for o in ("minmax", "rank", "sigmoid"):
            for prior in (1.0, 2.0):
                p = rs.resolved({"reading": "paper-literal", "o_norm": o, "prior": prior})
                rows += _rows(s, "betadesc", p, 20 + effect(p, s) + noise + rng.normal(0, 0.01, 8))
    return pd.DataFrame(rows)


def test_greedy_walk_adopts_only_clear_wins_on_both_scenes():
    space = rs.search_space(yaml.safe_load(CONFIG))
    assert [a.name for a in space.axes] == ["o_norm", "prior"] and space.axes[0].values[0] == "minmax"

    def effect(p, scene):  # rank clearly better on both scenes; prior 2 better on s1 only
        return (1.0 if p["o_norm"] == "rank" else 0.0) + (0.5 if p["prior"] == 2.0 and scene == "s1" else 0.0)

    df = _fake_results(space, effect)
    inc = rs.resolved(space.start)
    step = rs.evaluate_axis(df, space, space.axes[0], inc)
    assert step.candidate == "rank" and step.adopted
    assert step.delta["s1"].mean == pytest.approx(1.0, abs=0.02)
    inc = rs.with_value(inc, "o_norm", "rank")
    step2 = rs.evaluate_axis(df, space, space.axes[1], inc)
    assert step2.candidate == 2.0 and not step2.adopted  # no gain on s2
    assert rs.label(space, rs.with_value(inc, "prior", 2.0)) == "lit+o_norm=rank+prior=2"
    assert rs.overrides(space, inc) == {"reading": "paper-literal", "o_norm": "rank"}
    md = rs.selection_markdown(space, [step, step2], inc)
    assert "**adopted**" in md and "not adopted" in md and "| `o_norm` | `rank` |" in md


def test_missing_lists_readings_without_rows():
    space = rs.search_space(yaml.safe_load(CONFIG))
    df = _fake_results(space, lambda p, s: 0.0)
    base = rs.resolved(space.start)
    assert rs.missing(df, space, [base]) == []
    other = rs.with_value(base, "stat_norm", "rank")
    assert rs.missing(df, space, [other]) == [other]
