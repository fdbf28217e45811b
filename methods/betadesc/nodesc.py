"""The no-descriptor ablation's statistics: ℓ, s, u from each splat's own parameters [``nodesc_def``].

The paper's ablation (ii) is "pruning without descriptors but with Beta modelling" (L384), and it
says what descriptors add: "local structural context beyond individual splat parameters" (L384),
"individual splat parameters are often insufficient for robust reliability inference" (L162),
"decisions are derived from descriptor-level statistics rather than raw Gaussian parameters"
(L313). We read the no-descriptor variant as the same Eq. 4 with the same slots filled from the
*individual splat parameters* — "position, covariance, opacity, and spherical harmonics appearance
coefficients" (L164) — instead of from a neighbourhood descriptor (w = 1: there is no aggregation).
Its costs (6.78 s against the full method's 7.29 s per scene, L474) say it is more than an opacity
sort, too.

Per splat i, with log-scales log s_ik (k = 1..3), base colour c_i = clip(0.5 + SH_C0·f_dc,i, 0, 1)
and relative SH band powers f_iℓ (:func:`methods.betadesc.hsfh.band_fractions`):

* anisotropy a_i = std_k log s_ik (0 for a sphere; the splat's own "geometric contrast");
* extent     e_i = mean_k log s_ik (log of the geometric-mean radius: the splat's size);
* appearance dispersion d_i = var_rgb(c_i) + (1 − f_i0) (colour spread across the channels plus
  the share of SH energy above band 0: grey, view-independent splats are consistent).

Definitions (norm = ``stat_norm`` over the splats; o is the same normalised opacity as everywhere):

* ``splat-params`` (the default and paper-literal's): ℓ = 1 − norm(a), s = 1 − norm(d),
  u = norm(e) — each slot from a different parameter group: covariance shape (ℓ), SH appearance
  (s), covariance size (u: a large splat is "structurally distinctive", it alone covers a region);
* ``param-stats`` (v1's): ℓ = 1 − norm(a), s = 1 − norm(d), u = norm(a) — u and ℓ both from the
  shape (u = 1 − ℓ), size unused;
* ``opacity-only``: the s, ℓ, u terms dropped (their coefficients zeroed, :func:`methods.betadesc.
  evidence.opacity_only`). Then A and B depend on o alone, μ + γσ, A − B and every score are
  increasing in o, and the variant ranks exactly like the ``opacity`` baseline: it is that
  baseline's twin, not an ablation, and no reading's default.

Which of ``splat-params`` and ``param-stats`` is the default is decided by the pre-registered round
two (``ctc_configs/study/reading2.yaml``). Both are invariant to splat order and translation; scaling the
scene shifts every log-scale by one constant, which ``norm`` removes (up to float rounding).
"""

from __future__ import annotations

import numpy as np

from harness.core.scene import SH_C0, GaussianScene
from methods.betadesc.hsfh import band_fractions
from methods.betadesc.statistics import normalise

#: the values of ``nodesc_def`` that fill the s, ℓ, u slots (``opacity-only`` drops them)
DEFINITIONS = ("splat-params", "param-stats")


def splat_parameters(scene: GaussianScene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(anisotropy a, extent e, appearance dispersion d) per splat, float64 (module docstring)."""
    log_s = scene.scales_log.astype(np.float64)
    colour = np.clip(0.5 + SH_C0 * scene.sh_dc.astype(np.float64), 0.0, 1.0)
    view_share = 1.0 - band_fractions(scene)[:, 0] if scene.sh_degree > 0 else 0.0
    return log_s.std(axis=1), log_s.mean(axis=1), colour.var(axis=1) + view_share


def splat_statistics(scene: GaussianScene, how: str = "param-stats", norm: str = "robust") -> np.ndarray:
    """(N, 3) columns ℓ, s, u per splat under the no-descriptor definition ``how``."""
    if how not in DEFINITIONS:
        raise ValueError(f"unknown nodesc_def {how!r} for per-splat statistics; known: {', '.join(DEFINITIONS)}")
    a, e, d = splat_parameters(scene)
    shape = normalise(a, norm)
    s = 1.0 - normalise(d, norm)
    u = normalise(e, norm) if how == "splat-params" else shape
    return np.stack([1.0 - shape, s, u], axis=1)
