"""Random-effects meta-analysis over scenes: DerSimonian–Laird τ², the Hartung–Knapp–Sidik–Jonkman
interval and the prediction interval.

A claim about an average over scenes generalises over scenes, each measured with its own error. With
scene s's estimate y_s (a mean over its views) and its squared standard error v_s = s_s²/n_s:

* fixed-effect weights w_s = 1/v_s, μ_FE = Σ w_s y_s / Σ w_s, Cochran's Q = Σ w_s (y_s − μ_FE)²;
* **τ²** (DerSimonian–Laird): max(0, (Q − (k − 1)) / (Σ w_s − Σ w_s² / Σ w_s)), the variance of the
  true scene effects around their mean;
* random-effects weights w*_s = 1/(v_s + τ²), **μ** = Σ w*_s y_s / Σ w*_s, SE_RE² = 1/Σ w*_s;
* **HKSJ**: SE² = max(1, q) · SE_RE² with q = Σ w*_s (y_s − μ)² / (k − 1), and the interval
  μ ± t₀.₉₇₅,ₖ₋₁ · SE — the standard random-effects interval is too narrow with few scenes. q is
  truncated at 1 (the "modified" HKSJ of Röver, Knapp & Friede 2015): when the scenes agree more
  closely than their own errors suggest, the untruncated q < 1 would make the interval narrower
  than the standard one;
* **prediction interval** (Higgins, Thompson & Spiegelhalter 2009), where a new scene's true effect
  is expected: μ ± t₀.₉₇₅,ₖ₋₂ · √(τ² + SE_RE²), for k ≥ 3.

With q ≥ 1 these are statsmodels' ``combine_effects(method_re="dl")`` "random effect wls" row with
``use_t=True``, with q < 1 its "random effect" standard error with the same t quantile
(``tests/test_meta.py`` checks both, and cases by hand). A scene whose views all agree (v_s = 0)
would take every weight; its variance is floored at :data:`VAR_FLOOR`.

:class:`Estimate` is a mean with its standard error and degrees of freedom — :func:`of_values` over
a cell's views, :func:`pooled` over scenes by the model above — with its interval at any one-sided
level (the claims' Holm levels; 95 % two-sided by default).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

#: the smallest squared standard error a scene may carry (a cell whose views all differ by the same amount)
VAR_FLOOR = 1e-12
#: one-sided level of an interval: mean ± t₁₋α · SE at α = 0.025 is the 95 % two-sided interval
ALPHA = 0.025


@dataclass(frozen=True)
class RandomEffects:
    """μ with its HKSJ standard error (``df`` = k − 1), τ², Q, the HKSJ scale q (before truncation) and
    the prediction interval over k scenes."""

    mean: float
    se: float
    df: int
    tau2: float
    q: float
    k: int
    se_re: float
    pi: tuple[float, float]
    scale: float = 1.0

    def interval(self, level: float = 0.95) -> tuple[float, float]:
        """The two-sided HKSJ interval at ``level``."""
        if self.df < 1 or not np.isfinite(self.se):
            return (math.nan, math.nan)
        h = stats.t.ppf(0.5 + level / 2, self.df) * self.se
        return (self.mean - h, self.mean + h)

    @property
    def p_heterogeneity(self) -> float:
        """Cochran's Q test of τ² = 0 (χ² with k − 1 degrees of freedom)."""
        return float(stats.chi2.sf(self.q, self.k - 1)) if self.k > 1 else math.nan


def random_effects(effects, variances) -> RandomEffects:
    """Pool per-scene ``effects`` with their squared standard errors ``variances`` (module doc); k ≥ 2."""
    y = np.asarray(effects, dtype=np.float64)
    v = np.maximum(np.asarray(variances, dtype=np.float64), VAR_FLOOR)
    k = len(y)
    if k < 2 or len(v) != k or not (np.isfinite(y).all() and np.isfinite(v).all()):
        raise ValueError(f"random_effects needs k >= 2 finite effects with their variances, got {k}")
    w = 1.0 / v
    mu_fe = float(np.sum(w * y) / np.sum(w))
    q = float(np.sum(w * (y - mu_fe) ** 2))
    c = float(np.sum(w) - np.sum(w * w) / np.sum(w))
    tau2 = max(0.0, (q - (k - 1)) / c) if c > 0 else 0.0
    ws = 1.0 / (v + tau2)
    mu = float(np.sum(ws * y) / np.sum(ws))
    var_re = 1.0 / float(np.sum(ws))
    scale = float(np.sum(ws * (y - mu) ** 2)) / (k - 1)
    se = math.sqrt(max(1.0, scale) * var_re)
    if k >= 3:
        h = stats.t.ppf(0.975, k - 2) * math.sqrt(tau2 + var_re)
        pi = (mu - h, mu + h)
    else:
        pi = (math.nan, math.nan)
    return RandomEffects(mu, se, k - 1, tau2, q, k, math.sqrt(var_re), pi, scale)


@dataclass(frozen=True)
class Estimate:
    """A mean with its standard error and degrees of freedom over ``n`` values (views, repeats or
    scenes); ``tau2``, ``pi`` (prediction interval) for a random-effects estimate over scenes."""

    mean: float
    se: float
    df: int
    n: int
    tau2: float = math.nan
    pi: tuple[float, float] = (math.nan, math.nan)

    def interval(self, alpha: float = ALPHA) -> tuple[float, float]:
        """mean ± t₁₋α,df · SE (one-sided α per side); NaN without degrees of freedom."""
        if self.df < 1 or not (np.isfinite(self.mean) and np.isfinite(self.se)):
            return (math.nan, math.nan)
        h = stats.t.ppf(1.0 - alpha, self.df) * self.se
        return (self.mean - h, self.mean + h)

    def text(self, alpha: float = ALPHA, digits: int = 2) -> str:
        if not self.n or not np.isfinite(self.mean):
            return "–"
        lo, hi = self.interval(alpha)
        ci = f" [{lo:+.{digits}f}, {hi:+.{digits}f}]" if np.isfinite(lo) else ""
        return f"{self.mean:+.{digits}f}{ci}"


def of_values(values) -> Estimate:
    """The mean of ``values`` (finite ones) with SE = s/√n and n − 1 d.f."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if not v.size:
        return Estimate(math.nan, math.nan, 0, 0)
    se = float(v.std(ddof=1) / math.sqrt(v.size)) if v.size >= 2 else math.nan
    return Estimate(float(v.mean()), se, v.size - 1, int(v.size))


def pooled(per_scene: list[Estimate]) -> Estimate:
    """The random-effects estimate over scenes (HKSJ SE, k − 1 d.f., τ², prediction interval)."""
    ok = [e for e in per_scene if e.n >= 2 and np.isfinite(e.mean) and np.isfinite(e.se)]
    if len(ok) < 2:
        return ok[0] if len(ok) == 1 else Estimate(math.nan, math.nan, 0, 0)
    r = random_effects([e.mean for e in ok], [e.se ** 2 for e in ok])
    return Estimate(r.mean, r.se, r.df, r.k, r.tau2, r.pi)
