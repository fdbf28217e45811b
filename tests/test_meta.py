"""The random-effects meta-analysis over scenes (harness/report/meta.py): by hand, and against
statsmodels' independent implementation (DerSimonian–Laird τ², the HKSJ "random effect wls" row)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy import stats

from harness.report.meta import VAR_FLOOR, random_effects


def test_three_scenes_by_hand():
    # y = 1, 2, 4 with unit variances: μ_FE = 7/3, Q = 14/3, C = 2, τ² = 4/3; w* = 3/7, μ = 7/3,
    # SE_RE² = 7/9, HKSJ scale q = (3/7)(14/3)/2 = 1, so SE = √7/3
    r = random_effects([1.0, 2.0, 4.0], [1.0, 1.0, 1.0])
    assert (r.k, r.df) == (3, 2)
    assert r.mean == pytest.approx(7 / 3) and r.q == pytest.approx(14 / 3) and r.tau2 == pytest.approx(4 / 3)
    assert r.se == pytest.approx(math.sqrt(7) / 3) and r.se_re == pytest.approx(math.sqrt(7) / 3)
    lo, hi = r.interval()
    assert (hi - lo) / 2 == pytest.approx(4.302652729911275 * math.sqrt(7) / 3)  # t₀.₉₇₅,₂
    h = 12.706204736174698 * math.sqrt(4 / 3 + 7 / 9)  # t₀.₉₇₅,₁ · √(τ² + SE_RE²)
    assert r.pi == pytest.approx((7 / 3 - h, 7 / 3 + h))
    assert r.p_heterogeneity == pytest.approx(stats.chi2.sf(14 / 3, 2))


def test_the_hksj_scale_never_shrinks_the_interval_below_the_standard_one():
    # y = 1, 2 with variances 1, 4: w = 1, 1/4; μ_FE = 1.2; Q = 0.2 < k − 1, so τ² = 0; μ = 1.2,
    # SE_RE² = 0.8, q = 0.2: the untruncated HKSJ would give SE² = 0.16; truncated at 1: 0.8
    r = random_effects([1.0, 2.0], [1.0, 4.0])
    assert r.tau2 == 0.0 and r.mean == pytest.approx(1.2) and r.scale == pytest.approx(0.2)
    assert r.se == pytest.approx(math.sqrt(0.8))
    h = 12.706204736174698 * math.sqrt(0.8)
    assert r.interval() == pytest.approx((1.2 - h, 1.2 + h))
    assert all(math.isnan(x) for x in r.pi)  # k = 2: no prediction interval


def test_a_scene_whose_views_agree_exactly_is_floored_not_infinite():
    r = random_effects([1.0, 1.0, 1.0, 1.0], [0.0, 0.0, 0.0, 0.0])
    assert r.mean == 1.0 and r.tau2 == 0.0 and r.se == pytest.approx(math.sqrt(VAR_FLOOR / 4))
    r = random_effects([1.0, 3.0, 2.0], [0.0, 0.5, 0.5])
    assert np.isfinite(r.mean) and 1.0 <= r.mean < 2.0 and VAR_FLOOR > 0


@pytest.mark.parametrize("bad", [([1.0], [1.0]), ([1.0, np.nan], [1.0, 1.0]), ([1.0, 2.0], [1.0])])
def test_bad_input_is_refused(bad):
    with pytest.raises(ValueError, match="k >= 2"):
        random_effects(*bad)


@pytest.mark.parametrize("seed", range(12))
def test_equals_statsmodels(seed):
    ma = pytest.importorskip("statsmodels.stats.meta_analysis",
                             reason="statsmodels (the test extra) is the independent implementation")
    rng = np.random.default_rng(seed)
    k = int(rng.integers(3, 9))
    y = rng.normal(0, 2, k)
    v = rng.uniform(0.05, 1.5, k)
    ours = random_effects(y, v)
    with warnings.catch_warnings():  # it warns that per-scene intervals use the normal law (not used here)
        warnings.simplefilter("ignore")
        res = ma.combine_effects(y, v, method_re="dl", use_t=True)
        frame = res.summary_frame()
    row = frame.loc["random effect wls"]
    assert ours.tau2 == pytest.approx(res.tau2, rel=1e-9, abs=1e-12)
    assert ours.mean == pytest.approx(row["eff"], rel=1e-9)
    standard = frame.loc["random effect"]
    if ours.scale >= 1:  # the HKSJ row; below 1 the truncation keeps the standard error
        assert ours.se == pytest.approx(row["sd_eff"], rel=1e-9)
        assert ours.interval() == pytest.approx((row["ci_low"], row["ci_upp"]), rel=1e-9)
    else:
        assert ours.se == pytest.approx(standard["sd_eff"], rel=1e-9) and row["sd_eff"] < ours.se
    assert ours.scale == pytest.approx(res.scale_hksj_re, rel=1e-9)
    assert ours.q == pytest.approx(res.q, rel=1e-9)
    assert ours.se_re == pytest.approx(frame.loc["random effect", "sd_eff"], rel=1e-9)
