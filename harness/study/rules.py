"""The verdict rules of the claims table, as numbers in → verdict out (no run, no table).

Fixed before the data they judge: the study's document (``docs/claims.md``) states them in words and
names the commit that fixed them. Every claim of the paper has a **type**, read from its wording
(:data:`TYPES`), and a **band** for a measured quantity Δ (a paired per-view difference, a level, an
overhead). The quantities are :class:`Estimate`\\ s: a mean with its standard error and degrees of
freedom (:class:`harness.report.meta.Estimate`) — a scene's mean over its n paired views (SE = s/√n,
n − 1 d.f.) or a random-effects mean over k scenes (:func:`harness.report.meta.pooled`: HKSJ SE, k − 1 d.f.).

**Inside / outside a band, one-sided tests.** At one-sided level α an estimate's interval is
mean ± t₁₋α,df · SE. It is *inside* the band (lo, hi) when lo < its lower end and its upper end < hi,
*outside* when its upper end < lo or its lower end > hi. The p-values of those two statements are
``p_inside`` (for a two-sided band the larger of the two one-sided p-values, TOST) and
``p_outside`` (the smaller of the two sides' p-values): at level α the interval is inside (outside)
exactly when ``p_inside`` (``p_outside``) ≤ α. With α = 0.025 and one test this is the usual 95 %
two-sided interval.

**Holm across a claim's comparisons** (:func:`judge`). A claim with m estimates (scenes ×
comparisons, or its pooled comparisons) runs Holm's step-down twice at α = :data:`ALPHA`: once on the
``p_inside`` values, once on the ``p_outside`` values. Sorted ascending, the j-th (j = 1 … m) is
rejected when it and every earlier one are ≤ α/(m − j + 1): rejection on ``p_inside`` marks the
estimate **✓ holds**, on ``p_outside`` **✗ fails** (both cannot happen), else **? unclear**. A mark
shows the interval that decided it: for ✓ and ✗ the interval at the level α/(m − j + 1) that
rejected, for ? the interval at α/m (the widest Holm uses; it straddles a bound).

**Verdicts by type** (k = scenes with every cell the claim needs):

* fewer than :data:`MIN_SCENES` scenes: **underpowered**, whatever the type (numbers still shown);
* *universal* ("every row", "all datasets", "on breakfast and cinema"): every (scene, comparison) is
  one estimate of the Holm family; **fails** if any fails, **holds** if all hold, else
  **inconclusive**;
* *average* (a mean over scenes) and *equivalence* (a band both ways, of a mean over scenes): each
  comparison's random-effects estimate over the scenes is one estimate of the Holm family;
  **fails** if any fails, **holds** if all hold, else **inconclusive**;
* *existence* (heterogeneity: "helps on some scenes, hurts on others"): each scene gives two
  estimates of one Holm family of 2k, Δ > 0 and Δ < 0 (both p_inside); **holds** when some scene is
  above 0 and some scene below, **fails** when every scene is on the same side, else inconclusive;
* *effect size* (a stated magnitude): two verdicts by the rule of its unit (universal or average) —
  **direction** on the band (0, ∞) and **size** on (s/2, ∞), s the smallest effect the paper
  reports for the claim; the claim's verdict is "holds" if both hold, "fails" if either fails,
  else inconclusive.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from harness.report.meta import ALPHA, Estimate, of_values, pooled  # noqa: F401  (the rules' estimates)

#: fewer scenes than this cannot give a verdict ("underpowered")
MIN_SCENES = 4
HOLDS, FAILS, UNCLEAR = "holds", "fails", "unclear"
MARK = {HOLDS: "✓", FAILS: "✗", UNCLEAR: "?"}
UNIVERSAL, AVERAGE, EXISTENCE, EQUIVALENCE, EFFECT = "universal", "average", "existence", "equivalence", "effect size"
TYPES = (UNIVERSAL, AVERAGE, EXISTENCE, EQUIVALENCE, EFFECT)
#: the verdicts a claim can have (and "depends on the reading" when two readings disagree)
VERDICTS = ("holds", "fails", "inconclusive", "underpowered", "not testable here", "not comparable (render size)")
INF = math.inf


def _upper_p(t: float, df: int) -> float:
    """P(T ≥ t) for Student t with ``df`` d.f.; an undefined t (0/0) is no evidence (1)."""
    if math.isnan(t):
        return 1.0
    return float(stats.t.sf(t, df))


def _z(a: float, b: float, se: float) -> float:
    """(a − b)/se with se = 0 read as an exact value: ±inf, or NaN when a = b."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(np.float64(a - b) / np.float64(se))


def p_inside(e: Estimate, band: tuple[float, float]) -> float:
    """p-value of "Δ lies inside ``band``" (TOST for a two-sided band); 1 without an interval."""
    if e.df < 1 or not (np.isfinite(e.mean) and np.isfinite(e.se)):
        return 1.0
    lo, hi = band
    p_lo = _upper_p(_z(e.mean, lo, e.se), e.df) if lo > -INF else 0.0
    p_hi = _upper_p(_z(hi, e.mean, e.se), e.df) if hi < INF else 0.0
    return max(p_lo, p_hi)


def p_outside(e: Estimate, band: tuple[float, float]) -> float:
    """p-value of "Δ lies outside ``band``" (below it or above it); 1 without an interval."""
    if e.df < 1 or not (np.isfinite(e.mean) and np.isfinite(e.se)):
        return 1.0
    lo, hi = band
    p_below = _upper_p(_z(lo, e.mean, e.se), e.df) if lo > -INF else 1.0
    p_above = _upper_p(_z(e.mean, hi, e.se), e.df) if hi < INF else 1.0
    return min(p_below, p_above)


def holm(pvalues, alpha: float = ALPHA) -> list[float | None]:
    """Holm's step-down: for each p-value the level that rejected it, or None (not rejected)."""
    p = np.asarray(pvalues, dtype=np.float64)
    m = len(p)
    out: list[float | None] = [None] * m
    for j, i in enumerate(np.argsort(p, kind="stable")):
        level = alpha / (m - j)
        if p[i] > level:
            break
        out[i] = level
    return out


@dataclass(frozen=True)
class Mark:
    """One estimate's outcome in its claim's Holm family and the one-sided level of the interval
    that decided it (:func:`judge`)."""

    outcome: str
    alpha: float


def judge(estimates: list[Estimate], band: tuple[float, float], alpha: float = ALPHA) -> list[Mark]:
    """✓/✗/? of every estimate of one Holm family against ``band`` (module doc)."""
    m = len(estimates)
    if not m:
        return []
    held = holm([p_inside(e, band) for e in estimates], alpha)
    failed = holm([p_outside(e, band) for e in estimates], alpha)
    return [Mark(HOLDS, h) if h is not None else Mark(FAILS, f) if f is not None else Mark(UNCLEAR, alpha / m)
            for h, f in zip(held, failed)]


def combine(outcomes) -> str:
    """Several outcomes that must all hold: fails if any fails, holds if all hold, else unclear."""
    outcomes = list(outcomes)
    if FAILS in outcomes:
        return FAILS
    return HOLDS if outcomes and all(o == HOLDS for o in outcomes) else UNCLEAR


def family_verdict(marks: list[Mark]) -> str:
    """fails if any estimate fails, holds if all hold, else inconclusive."""
    got = combine(m.outcome for m in marks)
    return {HOLDS: "holds", FAILS: "fails"}.get(got, "inconclusive")


def existence_verdict(per_scene: list[Estimate], alpha: float = ALPHA) -> tuple[str, list[Mark], list[Mark]]:
    """(verdict, marks of Δ > 0, marks of Δ < 0) of the heterogeneity claim: one Holm family of 2k."""
    k = len(per_scene)
    up = [p_inside(e, (0.0, INF)) for e in per_scene]
    down = [p_inside(e, (-INF, 0.0)) for e in per_scene]
    levels = holm(up + down, alpha)
    ups = [Mark(HOLDS, a) if a is not None else Mark(UNCLEAR, alpha / (2 * k)) for a in levels[:k]]
    downs = [Mark(HOLDS, a) if a is not None else Mark(UNCLEAR, alpha / (2 * k)) for a in levels[k:]]
    any_up = any(u.outcome == HOLDS for u in ups)
    any_down = any(d.outcome == HOLDS for d in downs)
    if any_up and any_down:
        return "holds", ups, downs
    if all(u.outcome == HOLDS for u in ups) or all(d.outcome == HOLDS for d in downs):
        return "fails", ups, downs
    return "inconclusive", ups, downs


def effect_bands(smallest: float) -> dict[str, tuple[float, float]]:
    """The two bands of an effect-size claim: direction (> 0) and size (> half the smallest effect)."""
    return {"direction": (0.0, INF), "size": (smallest / 2.0, INF)}


def overall(verdicts) -> str:
    """An effect-size claim's verdict from its direction and size verdicts."""
    v = list(verdicts)
    if "underpowered" in v:
        return "underpowered"
    if "fails" in v:
        return "fails"
    return "holds" if v and all(x == "holds" for x in v) else "inconclusive"
