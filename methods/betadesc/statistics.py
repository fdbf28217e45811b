"""The paper's statistics s, ℓ, o, u ∈ [0, 1] (§3.2), from HSFH descriptors or per splat, in every
reading of :mod:`methods.betadesc.params` (the parameter names are given in brackets).

Normalisation [``stat_norm`` for s, ℓ, u over their population — voxels, or splats without
descriptors; ``o_norm`` for opacity over the splats] (the paper only says "normalized … ∈ [0,1]",
L227): ``robust`` = :func:`robust_unit`, ``clip((x − P5)/(P95 − P5), 0, 1)``; ``minmax`` =
``(x − min)/(max − min)``; ``rank`` = (average rank − 1)/(n − 1), ties sharing their mean rank.
Each is deterministic, invariant to permutations and to translation/scale of the raw values; a
degenerate population (all equal) carries no information and maps to 0.5. Opacity also has
``sigmoid``: the stored logit mapped to [0, 1] and not rescaled (v1; an all-zero-opacity scene then
gives o = 0 everywhere).

Descriptor statistics, per voxel j (notation of :mod:`methods.betadesc.hsfh`: g_j the 33-dim
geometric block, each angle histogram summing to 1 (all 0 when FPFH is undefined); f̄_j the band
powers; h_j the colour histograms):

* ``ℓ`` low geometric contrast = 1 − norm(raw ℓ) [``ell_def``]:
  ``nbhd-std`` (v1) σ_g with σ_g² = ⅓ mean_{k∈N(j)} ‖g_k − ḡ_j‖², the spread of the geometric block
  over the neighbourhood: a neighbourhood whose FPFH does not change gets ℓ → 1;
  ``dims-std`` the std of g_j across its 33 dimensions (the literal "standard deviation of the
  geometric descriptor block"; a peaked, planar histogram has a *high* std, hence a low ℓ).
* ``s`` appearance consistency = 1 − norm(raw s) [``s_def``]:
  ``nbhd-var`` (v1) the mean variance of the appearance components over the neighbourhood's splats —
  for the colour histogram the variance of the bin indicators, 1 − Σ_b h_b² averaged over channels;
  for SH degree ≥ 1 also 4·mean_ℓ var(f_ℓ), the two averaged;
  ``dims-var`` the variance across the components [f̄_j | h_j] of the voxel's appearance blocks.
* ``u`` geometric uniqueness = norm(raw u) [``u_def``]:
  ``dispersion`` (v1) per angle histogram (1 − Σ_b p_b²)/(1 − 1/11), averaged over the three (0 if
  FPFH is empty). Since std² across the 11 bins of a unit-sum histogram = (Σp² − 1/11)/11, this is a
  decreasing affine function of the literal std: v1 ranks by the *opposite* of the text;
  ``std-geo`` the std across the 33 geometric dimensions ("variability of descriptor components
  across dimensions", read on the geometric block the name "geometry uniqueness" points at);
  ``std-hsfh`` the std across the whole HSFH vector [g | f̄ | h] (the text's subject, "descriptor
  components"; every histogram block sums to 1, so the block scale is the paper's "normalized").

No-descriptor variant [``nodesc_def``]: ``opacity-only`` drops the s, ℓ, u terms (see
:mod:`methods.betadesc.pipeline`); ``param-stats`` (v1) per splat, from its own parameters (w = 1):

* ``u = norm(std_k log s_k)``: the splat's shape anisotropy;
* ``ℓ = 1 − u``: without a neighbourhood the only geometric contrast is the splat's own shape;
* ``s = 1 − norm(var_rgb(base colour) + (1 − f₀))``: grey, view-independent splats are consistent.

These use information the full method does not have (scale anisotropy, base-colour variance), which
is why ``opacity-only`` is the default ablation. Size is deliberately not used. Every quantity is
invariant to translation, and to scaling up to float rounding.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

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


def rank_unit(x: np.ndarray) -> np.ndarray:
    """(average rank − 1)/(n − 1) in [0, 1]: ties share their mean rank; 0.5 for n = 1 or all equal."""
    x = np.asarray(x, dtype=np.float64)
    if x.size <= 1:
        return np.full_like(x, 0.5)
    return (stats.rankdata(x, method="average") - 1.0) / (x.size - 1.0)


NORMALISERS = {"robust": robust_unit, "minmax": lambda x: robust_unit(x, 0.0, 100.0), "rank": rank_unit}


def normalise(x: np.ndarray, how: str) -> np.ndarray:
    """x mapped to [0, 1] by ``how`` (robust, minmax, rank; see the module docstring)."""
    try:
        return NORMALISERS[how](x)
    except KeyError:
        raise ValueError(f"unknown normalisation {how!r}; known: {', '.join(NORMALISERS)}") from None


def opacity_statistic(scene: GaussianScene, how: str = "sigmoid") -> np.ndarray:
    """o_i = sigmoid(opacity_logit_i) as float64, normalised over the splats by ``how`` unless sigmoid."""
    o = opacities(scene).astype(np.float64)
    return o if how == "sigmoid" else normalise(o, how)


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


def dims_std(block: np.ndarray) -> np.ndarray:
    """Population standard deviation of each row across its dimensions (columns)."""
    block = np.asarray(block, dtype=np.float64)
    mean = block.mean(axis=1, keepdims=True)
    return np.sqrt(np.mean((block - mean) ** 2, axis=1))


def appearance_block(desc: HSFH) -> np.ndarray:
    """The appearance components [f̄ | h] of every voxel's HSFH, (M, L+1 + 3B)."""
    return np.concatenate([desc.spectrum, desc.colour.reshape(len(desc.colour), -1)], axis=1)


def raw_ell(desc: HSFH, how: str) -> np.ndarray:
    if how == "nbhd-std":
        return geometric_contrast(desc)
    if how == "dims-std":
        return dims_std(desc.geometric)
    raise ValueError(f"unknown ell_def {how!r}")


def raw_s(desc: HSFH, how: str) -> np.ndarray:
    if how == "nbhd-var":
        return appearance_dispersion(desc)
    if how == "dims-var":
        return dims_std(appearance_block(desc)) ** 2
    raise ValueError(f"unknown s_def {how!r}")


def raw_u(desc: HSFH, how: str) -> np.ndarray:
    if how == "dispersion":
        return geometric_spread(desc.geometric)
    if how == "std-geo":
        return dims_std(desc.geometric)
    if how == "std-hsfh":
        return dims_std(desc.descriptor())
    raise ValueError(f"unknown u_def {how!r}")


def voxel_statistics(desc: HSFH, *, ell_def: str = "nbhd-std", s_def: str = "nbhd-var",
                     u_def: str = "dispersion", norm: str = "robust") -> np.ndarray:
    """(M, 3) columns ℓ, s, u per voxel, each in [0, 1] (defaults: the v1 reading)."""
    ell = 1.0 - normalise(raw_ell(desc, ell_def), norm)
    s = 1.0 - normalise(raw_s(desc, s_def), norm)
    u = normalise(raw_u(desc, u_def), norm)
    return np.stack([ell, s, u], axis=1)


def splat_statistics(scene: GaussianScene, norm: str = "robust") -> np.ndarray:
    """(N, 3) columns ℓ, s, u per splat for the ``param-stats`` no-descriptor variant (module doc)."""
    log_s = scene.scales_log.astype(np.float64)
    u = normalise(log_s.std(axis=1), norm)
    colour = np.clip(0.5 + SH_C0 * scene.sh_dc.astype(np.float64), 0.0, 1.0)
    view_share = 1.0 - band_fractions(scene)[:, 0] if scene.sh_degree > 0 else 0.0
    s = 1.0 - normalise(colour.var(axis=1) + view_share, norm)
    return np.stack([1.0 - u, s, u], axis=1)
