"""Paired per-view differences, their bootstrap CI, and the pre-registered greedy reading selection."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import yaml

from harness.study import reading_search as rs
from harness.study.paired import bootstrap_ci, compare, paired_difference


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
    md = rs.selection_markdown(space, [step, step2], {rs.METHOD: inc})
    assert "**adopted**" in md and "not adopted" in md
    assert "| axis | value |" in md and "| `o_norm` | `rank` |" in md  # one searched method: a row per axis
    assert "percentile-bootstrap" in md  # round one's rule names the bootstrap


def test_missing_lists_readings_without_rows():
    space = rs.search_space(yaml.safe_load(CONFIG))
    df = _fake_results(space, lambda p, s: 0.0)
    base = rs.resolved(space.start)
    assert rs.missing(df, space, [base]) == []
    other = rs.with_value(base, "stat_norm", "rank")
    assert rs.missing(df, space, [other]) == [other]


def test_round_two_config_encodes_the_registered_axes():
    from harness.core.paths import REPO_ROOT

    raw = yaml.safe_load((REPO_ROOT / "ctc_configs" / "study" / "reading2.yaml").read_text())
    space = rs.search_space(raw, interval="t", searched=rs.SEARCHED)
    assert space.interval == "t" and space.scenes == ("bonsai-7k-mini", "luigi") and space.ratio == 0.3
    assert space.starts == {"betadesc": {"reading": "round-one"}, "betadesc-nodesc": {"reading": "paper-literal"}}
    got = [(a.method, a.name, a.values) for a in space.axes]
    assert got == [
        (
            "betadesc",
            "ell_def+s_def+u_def",
            (("nbhd-std", "dims-var", "std-hsfh"), ("dims-peak", "dims-peak", "spread-hsfh")),
        ),
        ("betadesc", "s_def", ("dims-var", "nbhd-var", "dims-peak")),
        ("betadesc", "u_def", ("std-hsfh", "spread-hsfh", "dispersion", "std-geo")),
        ("betadesc", "ell_def", ("nbhd-std", "dims-std", "dims-peak")),
        ("betadesc", "voxel", (0.01, 0.02, 0.03, 0.1, 0.2, 0.3)),
        ("betadesc-nodesc", "nodesc_def", ("splat-params", "param-stats")),
    ]


def test_round_two_walk_joint_axis_then_single_axes_then_the_ablation():
    """A fake study: the joint direction axis wins on both scenes, then s_def=nbhd-var wins on one
    scene only (kept), and param-stats beats splat-params for the ablation on both (adopted)."""
    from harness.core.paths import REPO_ROOT

    raw = yaml.safe_load((REPO_ROOT / "ctc_configs" / "study" / "reading2.yaml").read_text())
    space = rs.search_space(raw, interval="t", searched=rs.SEARCHED, prefix="r1")
    rng = np.random.default_rng(0)
    noise = rng.normal(0, 0.05, 8)

    def effect(method, p, scene):
        if method == "betadesc-nodesc":
            return 0.8 if p["nodesc_def"] == "param-stats" else 0.0
        joint = 1.0 if (p["ell_def"], p["s_def"], p["u_def"]) == ("dims-peak", "dims-peak", "spread-hsfh") else 0.0
        return joint + (0.6 if p["s_def"] == "nbhd-var" and scene == "luigi" else 0.0)

    rows = [r for s in space.scenes for r in _rows(s, "random", {}, 20 + noise)]
    incumbents = {m: rs.resolved(p, m) for m, p in space.starts.items()}
    steps = []
    for axis in space.axes:  # what the driver does: run the missing readings, then evaluate
        m = axis.method
        df = pd.DataFrame(rows)
        for p in rs.missing(df, space, [rs.with_value(incumbents[m], axis, v) for v in axis.values], m):
            for s in space.scenes:
                rows += _rows(s, m, p, 20 + effect(m, p, s) + noise + rng.normal(0, 0.01, 8))
        step = rs.evaluate_axis(pd.DataFrame(rows), space, axis, incumbents[m])
        steps.append(step)
        if step.adopted:
            incumbents[m] = rs.with_value(incumbents[m], axis, step.candidate)
    assert [s.adopted for s in steps] == [True, False, False, False, False, True]
    assert steps[0].candidate == ("dims-peak", "dims-peak", "spread-hsfh")
    assert steps[1].current == "dims-peak" and steps[1].candidate == "nbhd-var"  # evaluated on the new incumbent
    # nbhd-var gains 0.6 on luigi but leaves the joint reading (-1.0): evaluated with the others at the incumbent
    assert steps[1].delta["luigi"].mean == pytest.approx(-0.4, abs=0.05) and steps[1].delta["luigi"].n == 8
    assert incumbents["betadesc-nodesc"]["nodesc_def"] == "param-stats"
    assert (
        rs.label(space, incumbents["betadesc"], "betadesc") == "r1+ell_def=dims-peak+s_def=dims-peak+u_def=spread-hsfh"
    )
    md = rs.selection_markdown(space, steps, incumbents)
    assert (
        "Student-t" in md
        and "of `betadesc-nodesc`" in md
        and "| betadesc-nodesc | `nodesc_def` | `param-stats` |" in md
    )
    assert "(incumbent `nbhd-std, dims-var, std-hsfh`)" in md
