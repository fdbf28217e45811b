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

Each reading is a raw quantity and an orientation: ``inverse`` maps it to 1 − norm(raw),
``direct`` to norm(raw). After each reading: whether it *preserves* or *reverses* the direction the
paper's words give (ℓ, s rise with neighbourhood homogeneity; u, "structurally distinctive", falls
with it), with Spearman ρ against homogeneity on luigi / grape-small / bonsai-7k-mini
(:mod:`harness.study.directions`; all five scenes in ``results/reading/directions.md``).

* ``ℓ`` low geometric contrast [``ell_def``] (against geometric homogeneity H_geo):
  ``nbhd-std`` (v1) 1 − norm(σ_g), σ_g² = ⅓ mean_{k∈N(j)} ‖g_k − ḡ_j‖², the spread of the geometric
  block over the neighbourhood — reverses (ρ −0.35 / −0.38 / −0.34: peaked FPFH histograms of flat
  regions change more from voxel to voxel than spread ones);
  ``dims-std`` 1 − norm(std of g_j across its 33 dimensions) (the literal "standard deviation of the
  geometric descriptor block") — reverses (−0.44 / −0.38 / −0.42: a planar histogram is peaked,
  its std high, its ℓ low);
  ``dims-peak`` norm(the same std) — preserves (+0.44 / +0.38 / +0.42).
* ``s`` appearance consistency [``s_def``] (against colour homogeneity H_app):
  ``nbhd-var`` (v1) 1 − norm(the mean variance of the appearance components over the neighbourhood's
  splats — for the colour histogram the variance of the bin indicators, 1 − Σ_b h_b² averaged over
  channels; for SH degree ≥ 1 also 4·mean_ℓ var(f_ℓ), the two averaged) — preserves (+0.93 / +0.87 / +0.88);
  ``dims-var`` 1 − norm(the variance across the components [f̄_j | h_j] of the voxel's appearance
  blocks) (the literal "inverse normalized variance of appearance-related descriptor components")
  — reverses (−0.93 / −0.83 / −0.88: one colour fills one bin, a peaked histogram has a high variance);
  ``dims-peak`` norm(the same variance) — preserves (+0.93 / +0.83 / +0.88).
* ``u`` geometric uniqueness [``u_def``] (against H_geo; the paper: higher = distinctive):
  ``dispersion`` (v1) norm(per angle histogram (1 − Σ_b p_b²)/(1 − 1/11), averaged over the three; 0 if
  FPFH is empty). Since std² across the 11 bins of a unit-sum histogram = (Σp² − 1/11)/11, this is a
  decreasing affine function of the literal std — preserves (−0.44 / −0.38 / −0.42);
  ``std-geo`` norm(std across the 33 geometric dimensions) ("variability of descriptor components
  across dimensions", read on the geometric block the name "geometry uniqueness" points at) —
  reverses (+0.44 / +0.38 / +0.42);
  ``std-hsfh`` norm(std across the whole HSFH vector [g | f̄ | h]) (the text's subject, "descriptor
  components"; every histogram block sums to 1, so the block scale is the paper's "normalized") —
  reverses (+0.37 / +0.01 / +0.55; against normal coherence +0.60 / +0.49 / +0.40);
  ``spread-hsfh`` 1 − norm(the same std) — preserves (−0.37 / −0.01 / −0.55).

The no-descriptor ablation's per-splat statistics [``nodesc_def``] are in :mod:`methods.betadesc.nodesc`.
"""

from __future__ import annotations

import numpy as np

from harness.core.scene import GaussianScene, opacities
from methods.betadesc.hsfh import BINS_PER_ANGLE, HSFH


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
    from scipy import stats  # 0.3 CPU-s to import, for a non-default normalisation only

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


def _dims_var_appearance(desc: HSFH) -> np.ndarray:
    return dims_std(appearance_block(desc)) ** 2


#: reading -> (raw statistic per voxel, orientation): "inverse" maps raw x to 1 − norm(x), "direct"
#: to norm(x); the docstring of each reading's parameter (params.py) says which way it points
def _dims_std_geometric(desc: HSFH) -> np.ndarray:
    return dims_std(desc.geometric)


def _dims_std_hsfh(desc: HSFH) -> np.ndarray:
    return dims_std(desc.descriptor())


def _spread_geometric(desc: HSFH) -> np.ndarray:
    return geometric_spread(desc.geometric)


ELL_READINGS = {"nbhd-std": (geometric_contrast, "inverse"),
                "dims-std": (_dims_std_geometric, "inverse"),
                "dims-peak": (_dims_std_geometric, "direct")}
S_READINGS = {"nbhd-var": (appearance_dispersion, "inverse"),
              "dims-var": (_dims_var_appearance, "inverse"),
              "dims-peak": (_dims_var_appearance, "direct")}
U_READINGS = {"dispersion": (_spread_geometric, "direct"),
              "std-geo": (_dims_std_geometric, "direct"),
              "std-hsfh": (_dims_std_hsfh, "direct"),
              "spread-hsfh": (_dims_std_hsfh, "inverse")}
_READINGS = {"ell": ("ell_def", ELL_READINGS), "s": ("s_def", S_READINGS), "u": ("u_def", U_READINGS)}


def _raw(stat: str, desc: HSFH, how: str) -> np.ndarray:
    name, table = _READINGS[stat]
    if how not in table:
        raise ValueError(f"unknown {name} {how!r}; known: {', '.join(table)}")
    return table[how][0](desc)


def raw_ell(desc: HSFH, how: str) -> np.ndarray:
    """ℓ before its orientation and normalisation, per voxel (``ell_def`` = ``how``)."""
    return _raw("ell", desc, how)


def raw_s(desc: HSFH, how: str) -> np.ndarray:
    """s before its orientation and normalisation, per voxel (``s_def`` = ``how``)."""
    return _raw("s", desc, how)


def raw_u(desc: HSFH, how: str) -> np.ndarray:
    """u before its orientation and normalisation, per voxel (``u_def`` = ``how``)."""
    return _raw("u", desc, how)


def voxel_statistic(desc: HSFH, stat: str, reading: str, norm: str = "robust") -> np.ndarray:
    """One statistic (``ell``, ``s`` or ``u``) per voxel in [0, 1] under ``reading``."""
    x = normalise(_raw(stat, desc, reading), norm)
    return 1.0 - x if _READINGS[stat][1][reading][1] == "inverse" else x


def voxel_statistics(desc: HSFH, *, ell_def: str = "nbhd-std", s_def: str = "nbhd-var",
                     u_def: str = "dispersion", norm: str = "robust") -> np.ndarray:
    """(M, 3) columns ℓ, s, u per voxel, each in [0, 1] (defaults: the v1 reading)."""
    return np.stack([voxel_statistic(desc, "ell", ell_def, norm), voxel_statistic(desc, "s", s_def, norm),
                     voxel_statistic(desc, "u", u_def, norm)], axis=1)
