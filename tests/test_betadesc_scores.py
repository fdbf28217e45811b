"""Beta posterior math and evidence (methods.betadesc.scores / evidence) against scipy and by hand."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from methods.betadesc.evidence import PRESETS, evidence, preset
from methods.betadesc.scores import beta_moments, beta_score

GRID = np.logspace(-12, 12, 25)


def _pairs():
    a, b = np.meshgrid(GRID, GRID, indexing="ij")
    return a.ravel(), b.ravel()


def test_moments_match_scipy_over_the_whole_range():
    a, b = _pairs()
    mu, nu, sigma = beta_moments(a, b)
    assert np.isfinite(mu).all() and np.isfinite(nu).all() and np.isfinite(sigma).all()
    ref_mean, ref_var = stats.beta.stats(a, b, moments="mv")
    np.testing.assert_allclose(mu, ref_mean, rtol=1e-12, atol=0)
    np.testing.assert_allclose(nu, b / (a + b), rtol=1e-12, atol=0)
    np.testing.assert_allclose(sigma, np.sqrt(ref_var), rtol=1e-10, atol=0)
    np.testing.assert_allclose(sigma, stats.beta.std(a, b), rtol=1e-10, atol=0)


@pytest.mark.parametrize("q", [0.05, 0.1, 0.5, 0.9])
def test_quantile_score_is_scipys_beta_ppf(q):
    a, b = _pairs()
    got = beta_score(a, b, "quantile", q=q)
    assert np.isfinite(got).all() and ((got >= 0) & (got <= 1)).all()
    np.testing.assert_allclose(got, stats.beta.ppf(q, a, b), rtol=1e-9, atol=1e-300)
    # independent check where the CDF is well conditioned: CDF(quantile) = q (a quantile that
    # is within a few ulps of 1 in float64 cannot be checked this way)
    ok = (a >= 1e-2) & (b >= 1e-2) & (a <= 1e6) & (b <= 1e6) & (got > 0) & (got < 1 - 1e-9)
    np.testing.assert_allclose(stats.beta.cdf(got[ok], a[ok], b[ok]), q, rtol=1e-6)


def test_quantile_is_a_lower_bound_and_orders_like_the_mean_for_equal_mass():
    a = np.array([2.0, 5.0, 8.0])
    b = 10.0 - a
    lo = beta_score(a, b, "quantile", q=0.1)
    assert (lo < a / 10).all() and np.all(np.diff(lo) > 0)


def test_ucb_lcb_literal_definitions():
    a, b = _pairs()
    mu, nu, sigma = beta_moments(a, b)
    np.testing.assert_array_equal(beta_score(a, b, "ucb", gamma=0.25), mu + 0.25 * sigma)
    np.testing.assert_array_equal(beta_score(a, b, "lcb", z=1.5), mu - 1.5 * sigma)
    np.testing.assert_array_equal(beta_score(a, b, "literal", gamma=0.25), nu + 0.25 * sigma)
    # the literal reading is the reversed consistent LCB: literal = 1 − (μ − γσ)
    np.testing.assert_allclose(beta_score(a, b, "literal", gamma=0.3), 1 - beta_score(a, b, "lcb", z=0.3),
                               atol=1e-15)


def test_ucb_rewards_uncertainty_at_equal_mean():
    # same mean 1/2, less evidence -> larger σ -> higher optimistic score, lower pessimistic score
    a = np.array([1.0, 10.0, 100.0])
    ucb = beta_score(a, a, "ucb")
    lcb = beta_score(a, a, "lcb")
    assert np.all(np.diff(ucb) < 0) and np.all(np.diff(lcb) > 0)


def test_unknown_score_and_bad_quantile_rejected():
    with pytest.raises(ValueError, match="unknown score"):
        beta_score(np.ones(2), np.ones(2), "mean")
    with pytest.raises(ValueError, match="quantile"):
        beta_score(np.ones(2), np.ones(2), "quantile", q=1.0)


def test_evidence_matches_equation_6_by_hand():
    s, ell, o, u, w = 0.3, 0.6, 0.8, 0.1, 0.7
    a, b = evidence(np.array([s]), np.array([ell]), np.array([o]), np.array([u]), np.array([w]),
                    preset("baseline"), prior=2.0)
    assert b[0] == pytest.approx(2.0 + w * (0.50 * s + 0.35 * ell + 0.20 * (1 - o)) + 0.20 * (1 - u), abs=1e-15)
    assert a[0] == pytest.approx(2.0 + w * (0.55 * o) + 0.50 * u, abs=1e-15)
    a2, _ = evidence(np.array([s]), np.array([ell]), np.array([o]), np.array([u]), np.array([w]),
                     preset("baseline"), prior=2.0, edge=np.array([0.4]), edge_weight=0.25)
    assert a2[0] == pytest.approx(a[0] + 0.1, abs=1e-15)


def test_presets_keep_the_baseline_evidence_mass():
    assert set(PRESETS) == {"baseline", "flat", "opacity-heavy", "structure-heavy"}
    for c in PRESETS.values():
        assert c.b_s + c.b_l + c.b_o + c.b_u == pytest.approx(1.25)
        assert c.a_o + c.a_u == pytest.approx(1.05)
    with pytest.raises(ValueError, match="unknown coefficient preset"):
        preset("heavy")
    with pytest.raises(ValueError, match="prior must be > 0"):
        evidence(np.ones(1), np.ones(1), np.ones(1), np.ones(1), 1.0, preset("flat"), prior=0.0)


def test_evidence_direction_opaque_unique_splats_gain_retention_confidence():
    zeros, ones = np.zeros(1), np.ones(1)
    keep_a, keep_b = evidence(zeros, zeros, ones, ones, ones, preset("baseline"))
    drop_a, drop_b = evidence(ones, ones, zeros, zeros, ones, preset("baseline"))
    assert beta_score(keep_a, keep_b)[0] > 0.5 > beta_score(drop_a, drop_b)[0]
    assert beta_score(keep_a, keep_b, "literal")[0] < beta_score(drop_a, drop_b, "literal")[0]
