"""harness.report.stats: the bootstrap against scipy and by hand, paired differences, near-identical views."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats as sst

from harness.report import stats


@pytest.mark.parametrize("n", [2, 3, 8, 25])
def test_bootstrap_matches_scipy_percentile(n):
    x = np.random.default_rng(n).normal(30.0, 2.0, n)
    lo, hi = stats.bootstrap_ci(x)
    ref = sst.bootstrap((x,), np.mean, method="percentile", n_resamples=10_000, confidence_level=0.95,
                        rng=np.random.default_rng(0)).confidence_interval
    assert lo == pytest.approx(ref.low, abs=1e-12) and hi == pytest.approx(ref.high, abs=1e-12)
    assert lo <= x.mean() <= hi


def test_paired_bootstrap_matches_scipy_paired():
    rng = np.random.default_rng(7)
    a = rng.normal(30, 3, 8)
    b = a - 0.5 + rng.normal(0, 0.2, 8)
    cur = pd.DataFrame({"frame": "", "view": [f"v{i}" for i in range(8)], "psnr": a, "near": False})
    ref = cur.assign(psnr=b)
    got = stats.paired(cur, ref, "psnr")
    boot = stats.bootstrap_ci(np.asarray(a - b))  # the percentile bootstrap of the differences = scipy's paired one
    want = sst.bootstrap((a, b), lambda p, q, axis: np.mean(p - q, axis=axis), paired=True, vectorized=True,
                         method="percentile", n_resamples=10_000, rng=np.random.default_rng(0)).confidence_interval
    assert got["delta"] == pytest.approx(np.mean(a - b))
    assert boot == (pytest.approx(want.low, abs=1e-12), pytest.approx(want.high, abs=1e-12))
    assert got["n_pairs"] == 8 and got["ci_low"] > 0  # a consistent +0.5 dB shows as an interval above 0


def test_bootstrap_by_hand_two_values():
    # resampled means of {0, 1} are 0, 0.5, 1 with probabilities 1/4, 1/2, 1/4 -> the 95 % interval is [0, 1]
    assert stats.bootstrap_ci([0.0, 1.0]) == (0.0, 1.0)
    assert stats.bootstrap_ci([5.0, 5.0, 5.0]) == (5.0, 5.0)
    assert all(math.isnan(v) for v in stats.bootstrap_ci([1.0]))
    assert all(math.isnan(v) for v in stats.bootstrap_ci([1.0, math.inf]))


def test_bootstrap_is_reproducible():
    x = np.arange(10.0) ** 1.5
    assert stats.bootstrap_ci(x) == stats.bootstrap_ci(x.copy())


def test_near_identical_covers_inf_the_100_db_line_and_mpeg_cap():
    df = pd.DataFrame({"psnr": [30.0, 99.9, 100.0, math.inf, np.nan, 40.0],
                       "rgb_psnr": [30.0, 30.0, 30.0, 30.0, 30.0, 999.99], "ssim": [1.0] * 6})
    assert stats.near_identical(df, ["psnr", "rgb_psnr", "ssim"]).tolist() == [False, False, True, True, False, True]
    assert stats.near_identical(df, ["ssim"]).tolist() == [False] * 6


def test_summary_and_paired_leave_near_identical_views_out_of_db_means():
    cur = pd.DataFrame({"frame": "", "view": ["a", "b", "c"], "psnr": [30.0, 197.0, math.inf],
                        "ssim": [0.9, 1.0, 1.0]})
    cur["near"] = stats.near_identical(cur, ["psnr"])
    s = stats.summary(cur["psnr"], cur["near"], "psnr")
    assert math.isnan(s.pop("std"))  # one informative view: no spread
    assert s == {"mean": 30.0, "median": 197.0, "n": 3, "n_near_identical": 2}
    ssim = stats.summary(cur["ssim"], cur["near"], "ssim")
    assert ssim["mean"] == pytest.approx(2.9 / 3) and ssim["std"] == pytest.approx(np.std([0.9, 1.0, 1.0], ddof=1))
    ref = cur.assign(psnr=[28.0, 35.0, 36.0], near=False)
    p = stats.paired(cur, ref, "psnr")
    assert p["delta"] == 2.0 and p["n_pairs"] == 1 and p["n_pairs_excluded"] == 2
    assert stats.paired(cur, ref.iloc[:2], "ssim")["n_pairs"] == 2  # bounded metrics keep every pair


def test_verdict():
    assert stats.verdict(0.1, 0.5, True) == "better"
    assert stats.verdict(0.1, 0.5, False) == "worse"
    assert stats.verdict(-0.1, 0.5, True) == "unclear"
    assert stats.verdict(np.nan, np.nan, True) == "unclear"


def _merge_diffs(cur, ref, metric, keys=("frame", "view")):
    """The inner-join definition paired_diffs implements (a pandas merge, NaN keys matching)."""
    keys = [k for k in keys if k in cur and k in ref]
    j = cur[keys + [metric, "near"]].merge(ref[keys + [metric, "near"]], on=keys, suffixes=("", "_ref"))
    d = (j[metric] - j[f"{metric}_ref"]).to_numpy(dtype=float)
    excluded = (j["near"] | j["near_ref"]).to_numpy(dtype=bool)
    return d[~excluded & np.isfinite(d)], int(excluded.sum())


@pytest.mark.parametrize("seed", range(20))
def test_paired_diffs_equals_an_inner_join(seed):
    import pandas as pd

    from harness.report.stats import paired_diffs

    rng = np.random.default_rng(seed)

    def frame(n):
        return pd.DataFrame({"frame": rng.choice([np.nan, 0.0, 1.0], n), "view": rng.choice(["a", "b", "c"], n),
                             "psnr": np.where(rng.random(n) < 0.1, np.inf, rng.normal(40, 5, n)),
                             "near": rng.random(n) < 0.2})

    cur, ref = frame(int(rng.integers(0, 9))), frame(int(rng.integers(0, 9)))
    d, excluded = paired_diffs(cur, ref, "psnr")
    d0, excluded0 = _merge_diffs(cur, ref, "psnr")
    np.testing.assert_array_equal(d, d0)
    assert excluded == excluded0


# --------------------------------------------------------------------------- the house interval
@pytest.mark.parametrize("n", [2, 3, 8, 25])
def test_t_interval_matches_scipy(n):
    x = np.random.default_rng(n).normal(30.0, 2.0, n)
    lo, hi = stats.mean_ci(x)
    ref = sst.t.interval(0.95, n - 1, loc=x.mean(), scale=sst.sem(x))
    assert (lo, hi) == (pytest.approx(ref[0], abs=1e-12), pytest.approx(ref[1], abs=1e-12))
    assert stats.INTERVAL == "t" and "Student-t" in stats.INTERVAL_DESCRIPTION


def test_t_interval_edge_cases():
    assert stats.t_ci([5.0, 5.0, 5.0]) == (5.0, 5.0)
    assert all(math.isnan(v) for v in stats.t_ci([1.0]))
    assert all(math.isnan(v) for v in stats.t_ci([1.0, math.inf]))
    # two values 0 and 1: mean 0.5, s = 1/√2, t(0.975, 1) = 12.706 -> ± 12.706 · 0.5
    lo, hi = stats.t_ci([0.0, 1.0])
    assert hi - 0.5 == pytest.approx(12.7062047 * 0.5, rel=1e-7) and lo == pytest.approx(1.0 - hi)


def test_coverage_at_eight_views_t_holds_the_percentile_bootstrap_does_not():
    """Known mean, n = 8 paired differences (a default study's views): the t interval covers ~95 %,
    the percentile bootstrap the tables used before ~88 % (normal) — the reason for the switch."""
    from harness.benchmarks.intervals import coverage

    normal = coverage("normal", 8, reps=2000, bca_reps=0, seed=11)
    heavy = coverage("t3", 8, reps=2000, bca_reps=0, seed=11)
    assert 0.935 <= normal["t"]["coverage"] <= 0.965  # 0.95 ± 3 binomial SE (0.0049 at 2,000)
    assert heavy["t"]["coverage"] >= 0.935
    assert normal["percentile bootstrap"]["coverage"] <= 0.91 and heavy["percentile bootstrap"]["coverage"] <= 0.92


def test_paired_uses_the_house_interval():
    rng = np.random.default_rng(3)
    a = rng.normal(30, 3, 8)
    cur = pd.DataFrame({"frame": "", "view": [f"v{i}" for i in range(8)], "psnr": a, "near": False})
    ref = cur.assign(psnr=a - 0.5 + rng.normal(0, 0.3, 8))
    got = stats.paired(cur, ref, "psnr")
    assert (got["ci_low"], got["ci_high"]) == stats.t_ci(cur["psnr"] - ref["psnr"])
