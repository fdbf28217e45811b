"""The paper's statistics s, ℓ, o, u ∈ [0, 1] (§3.2), from HSFH descriptors or per splat.

Normalisation (the paper only says "normalised"): a raw statistic x is mapped by
:func:`robust_unit`, ``clip((x − P5)/(P95 − P5), 0, 1)`` with P5/P95 the 5th/95th percentiles
over the population (voxels, or splats for the no-descriptor variant). It is deterministic,
invariant to permutations, to translation/scale of the raw values, and insensitive to outliers.
A degenerate population (P95 = P5) carries no information and maps to 0.5.

Descriptor statistics, per voxel j (notation of :mod:`methods.betadesc.hsfh`):

* ``ℓ`` low geometric contrast = 1 − unit(σ_g), with σ_g² = ⅓ mean_{k∈N(j)} ‖g_k − ḡ_j‖² the
  spread of the geometric block over the neighbourhood ("inverse normalised std of the geometric
  block"): a neighbourhood whose FPFH does not change (homogeneous surface) gets ℓ → 1.
* ``s`` appearance consistency = 1 − unit(d_a): d_a is the mean variance of the appearance
  components over the neighbourhood's splats — for the colour histogram the variance of the bin
  indicators, Σ_b h_b(1 − h_b) = 1 − Σ_b h_b² averaged over channels; for SH degree ≥ 1 also
  4·mean_ℓ var(f_ℓ) (f ∈ [0,1], so each term is in [0,1]), the two averaged.
* ``u`` geometric uniqueness = unit(spread of g_j across its dimensions): per angle histogram
  (1 − Σ_b p_b²)/(1 − 1/11), averaged over the three. We read "variability across dimensions" as
  dispersion of the descriptor's mass over its bins: a plane puts every angle in one bin (u → 0),
  edges, corners and fine structure spread it (u → 1). The literal standard deviation across bins
  would rank planes as most distinctive, contradicting the paper's intent. A voxel without
  neighbours (empty FPFH) has no structural evidence: raw spread 0.

Opacity ``o = sigmoid(opacity_logit)`` per splat (already in [0, 1]; no rescaling, so an all-zero
opacity scene gives o = 0 everywhere).

No-descriptor variant (per splat, from the splat's own parameters only; w = 1):

* ``u = unit(std_k log s_k)``: the "variability across dimensions" of the splat's own geometric
  parameters, i.e. its shape anisotropy — needles and discs (thin structure, surfaces) are
  distinctive, round blobs are not;
* ``ℓ = 1 − u``: without a neighbourhood, the only geometric contrast a splat has is its own shape,
  so low contrast and uniqueness collapse onto the same quantity (the ablation has one geometric
  degree of freedom less, which is the point of the ablation);
* ``s = 1 − unit(var_rgb(base colour) + (1 − f₀))``: grey, view-independent splats are consistent
  (1 − f₀ is the view-dependent share of SH energy, 0 at degree 0).

Size is deliberately not used: ranking by volume would make this ablation a volume pruner.
Every quantity is invariant to translation, and to scaling up to float rounding (a global scale
shifts every log s by the same constant, which the std removes).
"""

from __future__ import annotations

import numpy as np

from harness.core.scene import SH_C0, GaussianScene, opacities
from methods.betadesc.hsfh import BINS_PER_ANGLE, HSFH, band_fractions


def robust_unit(x: np.ndarray, lo_pct: float = 5.0, hi_pct: float = 95.0) -> np.ndarray:
    """Percentile min–max normalisation to [0, 1] (0.5 everywhere for a degenerate population)."""
    x = np.asarray(x, dtype=np.float64)
    if x.size == 0:
        return x.copy()
    lo, hi = np.percentile(x, [lo_pct, hi_pct])
    span = hi - lo
    if not span > 1e-12 * max(1.0, abs(hi), abs(lo)):
        return np.full_like(x, 0.5)
    return np.clip((x - lo) / span, 0.0, 1.0)


def opacity_statistic(scene: GaussianScene) -> np.ndarray:
    """o_i = sigmoid(opacity_logit_i) as float64."""
    return opacities(scene).astype(np.float64)


def geometric_spread(geometric: np.ndarray) -> np.ndarray:
    """Mass dispersion of the three angle histograms: mean of (1 − Σp²)/(1 − 1/11); 0 if empty."""
    blocks = geometric.reshape(len(geometric), 3, BINS_PER_ANGLE)
    total = blocks.sum(axis=2)
    spread = (1.0 - (blocks * blocks).sum(axis=2)) / (1.0 - 1.0 / BINS_PER_ANGLE)
    return np.where(total > 0, spread, 0.0).mean(axis=1)


def geometric_contrast(desc: HSFH) -> np.ndarray:
    """σ_g per voxel: RMS deviation of the geometric block over N(j) (per angle histogram)."""
    adj = desc.adjacency()
    n = np.diff(desc.indptr).astype(np.float64)[:, None]
    g = desc.geometric
    mean = (adj @ g) / n
    sq = (adj @ (g * g).sum(axis=1, keepdims=True)) / n
    var = np.maximum(sq[:, 0] - (mean * mean).sum(axis=1), 0.0) / 3.0
    return np.sqrt(var)


def appearance_dispersion(desc: HSFH) -> np.ndarray:
    """d_a per voxel: mean variance of the appearance components over N(j) (see module doc)."""
    colour = (1.0 - (desc.colour * desc.colour).sum(axis=2)).mean(axis=1)
    if desc.spectrum.shape[1] == 1:
        return colour
    spectral = np.clip(4.0 * desc.spectrum_var.mean(axis=1), 0.0, 1.0)
    return 0.5 * (colour + spectral)


def voxel_statistics(desc: HSFH) -> np.ndarray:
    """(M, 3) columns ℓ, s, u per voxel, each in [0, 1]."""
    ell = 1.0 - robust_unit(geometric_contrast(desc))
    s = 1.0 - robust_unit(appearance_dispersion(desc))
    u = robust_unit(geometric_spread(desc.geometric))
    return np.stack([ell, s, u], axis=1)


def splat_statistics(scene: GaussianScene) -> np.ndarray:
    """(N, 3) columns ℓ, s, u per splat for the no-descriptor variant (see module doc)."""
    log_s = scene.scales_log.astype(np.float64)
    u = robust_unit(log_s.std(axis=1))
    colour = np.clip(0.5 + SH_C0 * scene.sh_dc.astype(np.float64), 0.0, 1.0)
    view_share = 1.0 - band_fractions(scene)[:, 0] if scene.sh_degree > 0 else 0.0
    s = 1.0 - robust_unit(colour.var(axis=1) + view_share)
    return np.stack([1.0 - u, s, u], axis=1)
