"""Beta posterior moments and the ranking scores (the paper's §3.3), higher = keep.

The retention probability p_i ~ Beta(A_i, B_i) (A = retention evidence, B = pruning evidence):

    μ_i = A/(A+B),   σ_i² = AB / ((A+B)²(A+B+1)) = μ(1−μ)/(A+B+1).

Computed as μ = 1/(1 + B/A) and ν = 1/(1 + A/B) (no cancellation; a chain of correctly rounded,
monotone operations, so μ is exactly non-decreasing in A and non-increasing in B even where a step
is below one ulp — A/(A+B) is not), σ² = μν/(A+B+1): finite and accurate in float64 for A, B
anywhere in [1e-12, 1e12].

Scores (param ``score``):

* ``ucb`` (default) μ + γσ, γ = 0.25 — the optimistic confidence of Eq. 8 on retention confidence.
* ``lcb`` μ − zσ — the Gaussian-moment lower bound of Eq. 7.
* ``quantile`` the exact q-quantile of Beta(A, B), ``scipy.special.betaincinv(A, B, q)`` (Eq. 7's
  BetaInvCDF; q < ½ is a lower bound).
* ``literal`` (B/(A+B)) + γσ — the paper's text taken literally: Eq. 2 calls B/(A+B) the expected
  *pruning* probability, and Eq. 9 prunes the splats whose score is *below* τ. Ranking ascending
  then removes first the splats with the most *retention* evidence (opaque, distinctive) and keeps
  the safest-to-prune ones: the opposite of the method's stated intent, hence the erratum
  (docs/reading.md, "The score sign"). It is exactly 1 − (μ − γσ) of the consistent reading, i.e. the
  reversed LCB order.
"""

from __future__ import annotations

import numpy as np

SCORES = ("ucb", "lcb", "quantile", "literal")


def beta_moments(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(μ = A/(A+B), ν = B/(A+B), σ) of Beta(A, B), float64."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    mu = 1.0 / (1.0 + b / a)
    nu = 1.0 / (1.0 + a / b)
    sigma = np.sqrt(mu * nu / (a + b + 1.0))
    return mu, nu, sigma


def beta_score(a: np.ndarray, b: np.ndarray, kind: str = "ucb", gamma: float = 0.25,
               z: float = 1.0, q: float = 0.1) -> np.ndarray:
    """The ranking score of kind ``kind`` (see module doc) for Beta(A, B) posteriors."""
    if kind == "quantile":
        if not 0.0 < q < 1.0:
            raise ValueError(f"quantile q must be in (0, 1), got {q}")
        from scipy import special  # for this score only: not imported by the default ranking

        return special.betaincinv(np.asarray(a, np.float64), np.asarray(b, np.float64), q)
    mu, nu, sigma = beta_moments(a, b)
    if kind == "ucb":
        return mu + gamma * sigma
    if kind == "lcb":
        return mu - z * sigma
    if kind == "literal":
        return nu + gamma * sigma
    raise ValueError(f"unknown score {kind!r}; known: {', '.join(SCORES)}")
