"""Beta posterior and evidence under extreme inputs: A, B over 1e-12…1e12, float32 and float64, ties.

Truth: scipy.stats.beta in float64 (mean, std, ppf) on the same (float64-cast) inputs; the bounds
0 ≤ μ ≤ 1, σ ≤ ½ and the monotonicity the math guarantees — μ = A/(A+B) and every Beta quantile
increase with A and decrease with B (Beta(A, B) is stochastically increasing in A).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy import stats

from methods.betadesc.evidence import PRESETS, evidence
from methods.betadesc.scores import SCORES, beta_moments, beta_score
from tests.stress.budget import examples

pytestmark = pytest.mark.stress

log_ab = st.floats(min_value=-12.0, max_value=12.0, allow_nan=False)
dtypes = st.sampled_from([np.float32, np.float64])


def _ab(exps_a, exps_b, dtype):
    return (10.0 ** np.asarray(exps_a)).astype(dtype), (10.0 ** np.asarray(exps_b)).astype(dtype)


@examples(40, 3000)
@given(st.lists(st.tuples(log_ab, log_ab), min_size=1, max_size=64), dtypes)
def test_moments_and_scores_match_scipy_and_stay_finite(stress_counts, pairs, dtype):
    a, b = _ab([p[0] for p in pairs], [p[1] for p in pairs], dtype)
    stress_counts.add("beta", moments=len(a))
    mu, nu, sigma = beta_moments(a, b)
    a64, b64 = a.astype(np.float64), b.astype(np.float64)
    for x in (mu, nu, sigma):
        assert x.dtype == np.float64 and np.isfinite(x).all()
    assert ((mu >= 0) & (mu <= 1) & (nu >= 0) & (nu <= 1)).all() and (sigma <= 0.5).all()
    np.testing.assert_allclose(mu, stats.beta.mean(a64, b64), rtol=1e-12, atol=0)
    np.testing.assert_allclose(sigma, stats.beta.std(a64, b64), rtol=1e-9, atol=0)
    np.testing.assert_allclose(mu + nu, 1.0, rtol=0, atol=4e-16)
    for kind in SCORES:
        s = beta_score(a, b, kind, gamma=0.25, z=1.0, q=0.1)
        assert s.shape == a.shape and np.isfinite(s).all(), kind
    np.testing.assert_allclose(beta_score(a, b, "quantile", q=0.1), stats.beta.ppf(0.1, a64, b64),
                               rtol=1e-9, atol=1e-300)


@examples(40, 2000)
@given(log_ab, st.lists(log_ab, min_size=2, max_size=40), dtypes, st.booleans())
def test_mean_and_quantile_are_monotone(stress_counts, fixed, varying, dtype, vary_a):
    """μ and the q-quantile are non-decreasing in A (B fixed) and non-increasing in B (A fixed)."""
    grid = np.sort(10.0 ** np.asarray(varying)).astype(dtype)
    grid = np.sort(grid)  # float32 rounding keeps the order, sorting again is harmless
    other = np.full_like(grid, dtype(10.0 ** fixed))
    a, b = (grid, other) if vary_a else (other, grid)
    stress_counts.add("beta", monotone=len(grid))
    mu = beta_moments(a, b)[0]
    quant = beta_score(a, b, "quantile", q=0.1)
    step_mu, step_q = np.diff(mu), np.diff(quant)
    # a quantile below the float64 normal range is unresolved: scipy returns 0 or its 2.2e-308 floor
    # (e.g. q=0.1 of Beta(1e-3, 1) is 1e-1000), so steps between such values carry no order
    underflow = (quant[:-1] < 1e-300) & (quant[1:] < 1e-300)
    step_q = np.where(underflow, 0.0, step_q)
    # monotone up to rounding: neighbours one ulp apart (10**-2.2e-16 vs 10**0) may step back by a few
    # ulps of the value (seen: -4.0e-27 on a quantile of 1.9e-12, relative 2e-15), never more
    tol_mu = 1e-12 * np.maximum(np.abs(mu[:-1]), np.abs(mu[1:]))
    tol_q = 1e-12 * np.maximum(np.abs(quant[:-1]), np.abs(quant[1:]))
    if vary_a:
        assert (step_mu >= -tol_mu).all() and (step_q >= -tol_q).all()
    else:
        assert (step_mu <= tol_mu).all() and (step_q <= tol_q).all()


@examples(20, 1000)
@given(st.lists(st.tuples(log_ab, log_ab), min_size=1, max_size=16), dtypes)
def test_ties_give_identical_scores_and_equal_evidence_gives_one_half(stress_counts, pairs, dtype):
    a, b = _ab([p[0] for p in pairs], [p[1] for p in pairs], dtype)
    a2, b2 = np.concatenate([a, a]), np.concatenate([b, b])
    stress_counts.add("beta", ties=len(a2))
    for kind in SCORES:
        s = beta_score(a2, b2, kind)
        np.testing.assert_array_equal(s[: len(a)], s[len(a):])
    mu, nu, _ = beta_moments(a, a)
    np.testing.assert_array_equal(mu, 0.5)
    np.testing.assert_array_equal(nu, 0.5)


unit = st.floats(min_value=0.0, max_value=1.0, allow_nan=False)


@examples(40, 2000)
@given(st.lists(st.tuples(unit, unit, unit, unit, unit, unit), min_size=1, max_size=64),
       st.floats(min_value=1e-12, max_value=1e12), st.sampled_from(sorted(PRESETS)), dtypes,
       st.floats(min_value=0.0, max_value=1.0))
def test_evidence_from_any_statistics_is_a_valid_posterior(stress_counts, rows, prior, name, dtype, edge_w):
    """Statistics anywhere in [0, 1] (exact 0 and 1 included) and any prior give A, B ≥ prior > 0,
    finite scores, and μ + γσ within [0, 1 + γ/2]. (float32 statistics: see the known issue below.)"""
    s, ell, o, u, w, e = (np.asarray(np.asarray(c, dtype=dtype), dtype=np.float64) for c in zip(*rows))
    stress_counts.add("beta", evidence=len(s))
    a, b = evidence(s, ell, o, u, w, PRESETS[name], prior=prior, edge=e, edge_weight=edge_w)
    assert a.dtype == np.float64 and b.dtype == np.float64
    assert np.isfinite(a).all() and np.isfinite(b).all()
    assert (a >= prior * (1 - 1e-12)).all() and (b >= prior * (1 - 1e-12)).all()
    ucb = beta_score(a, b, "ucb", gamma=0.25)
    assert np.isfinite(ucb).all() and (ucb >= 0).all() and (ucb <= 1.125).all()
    np.testing.assert_allclose(beta_moments(a, b)[0], stats.beta.mean(a, b), rtol=1e-12)


def test_extreme_corners_exactly(stress_counts):
    """The four corners of the range and the diagonal, against scipy."""
    v = np.array([1e-12, 1.0, 1e12])
    a, b = (x.ravel() for x in np.meshgrid(v, v, indexing="ij"))
    stress_counts.add("beta", corners=len(a))
    mu, _, sigma = beta_moments(a, b)
    np.testing.assert_allclose(mu, stats.beta.mean(a, b), rtol=1e-12)
    np.testing.assert_allclose(sigma, stats.beta.std(a, b), rtol=1e-9)
    assert mu[2] < 1e-23 and mu[6] == 1.0  # A=1e-12, B=1e12 -> μ = 1e-24; reversed -> 1 exactly


def test_evidence_float32_statistics_keep_float64_precision():
    z = np.zeros(1, np.float32)
    a, _ = evidence(z, z, z, z, z, PRESETS["baseline"], prior=1e-12)
    assert a[0] == 1e-12  # Eq. 6 with all statistics 0 is exactly the prior, in float64
