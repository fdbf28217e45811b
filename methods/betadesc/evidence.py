"""Beta evidence from the statistics (the paper's Eq. 4, L248–249), with coefficient presets.

    B_i = B₀ + w_i (b_s s_i + b_ℓ ℓ_i + b_o (1 − o_i)) + b_u (1 − u_i)     (safe-pruning evidence)
    A_i = A₀ + w_i (a_o o_i) + a_u u_i + a_e e_i                          (retention evidence)

exactly as Eq. 4 places the parentheses: w scales the neighbourhood-aggregated s, ℓ and the
opacity terms, the uniqueness terms are added unweighted. ``e_i`` is the optional view-aware
edge proxy (:mod:`methods.betadesc.view_aware`; 0 without cameras). The prior A₀ = B₀ > 0 (param
``prior``, default 1: a uniform Beta(1, 1) before any evidence; the paper gives no initial value).

Presets (``b_s, b_ℓ, b_o, b_u`` | ``a_o, a_u``). Only ``baseline`` is the paper's: L468 names the
other three but gives no values, so **flat, opacity-heavy and structure-heavy are this project's own
invention** (as is the rule that every preset keeps the baseline's total masses Σb = 1.25 and
Σa = 1.05, so prior strength and posterior width stay comparable and only the emphasis moves):

* ``baseline``        0.50 0.35 0.20 0.20 | 0.55 0.50   (the paper, Eq. 4)
* ``flat``            0.3125 ×4           | 0.525 0.525 (ours: no term favoured)
* ``opacity-heavy``   0.35 0.25 0.45 0.20 | 0.80 0.25   (ours: opacity drives both sides)
* ``structure-heavy`` 0.35 0.50 0.10 0.30 | 0.35 0.70   (ours: geometric homogeneity / uniqueness drive)

``coeff_order="prose"`` swaps b_s and b_ℓ: L254 lists "geometric homogeneity, appearance consistency"
in that order against Eq. 4's 0.50 on s. :func:`opacity_only` zeroes the s, ℓ, u coefficients (the
no-descriptor ablation without statistics the full method lacks).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class Coefficients:
    b_s: float
    b_l: float
    b_o: float
    b_u: float
    a_o: float
    a_u: float


PRESETS: dict[str, Coefficients] = {
    "baseline": Coefficients(0.50, 0.35, 0.20, 0.20, 0.55, 0.50),
    "flat": Coefficients(0.3125, 0.3125, 0.3125, 0.3125, 0.525, 0.525),
    "opacity-heavy": Coefficients(0.35, 0.25, 0.45, 0.20, 0.80, 0.25),
    "structure-heavy": Coefficients(0.35, 0.50, 0.10, 0.30, 0.35, 0.70),
}


def preset(name: str, order: str = "eq4") -> Coefficients:
    """The coefficients of preset ``name``; ``order="prose"`` swaps b_s and b_ℓ (module docstring)."""
    try:
        c = PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown coefficient preset {name!r}; known: {', '.join(PRESETS)}") from None
    if order == "eq4":
        return c
    if order == "prose":
        return replace(c, b_s=c.b_l, b_l=c.b_s)
    raise ValueError(f"unknown coefficient order {order!r}; known: eq4, prose")


def opacity_only(c: Coefficients) -> Coefficients:
    """``c`` without the descriptor terms: only the opacity coefficients b_o, a_o remain."""
    return replace(c, b_s=0.0, b_l=0.0, b_u=0.0, a_u=0.0)


def evidence(s: np.ndarray, ell: np.ndarray, o: np.ndarray, u: np.ndarray, w: np.ndarray | float,
             coeffs: Coefficients, prior: float = 1.0, edge: np.ndarray | float = 0.0,
             edge_weight: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) per splat, float64, from statistics in [0, 1] (Eq. 6 plus the optional edge term)."""
    if not prior > 0:
        raise ValueError(f"prior must be > 0 (Beta(A, B) needs A, B > 0), got {prior}")
    c = coeffs
    s, ell, o, u, w, edge = (np.asarray(x, dtype=np.float64) for x in (s, ell, o, u, w, edge))
    b = prior + w * (c.b_s * s + c.b_l * ell + c.b_o * (1.0 - o)) + c.b_u * (1.0 - u)
    a = prior + w * (c.a_o * o) + c.a_u * u + edge_weight * edge
    return a, b
