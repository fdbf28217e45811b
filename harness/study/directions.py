"""Which way each reading of ℓ, s and u points: its rank correlation with neighbourhood homogeneity.

The paper states a direction for every statistic of Eq. 4 (L233-242, L256):

* ℓ "low geometric contrast … such that homogeneous neighbourhoods yield high values";
* s "low-frequency appearance consistency" — and "Homogeneous neighbourhoods with low geometric and
  appearance variation increase pruning evidence" (s and ℓ both feed B, the pruning evidence);
* u "geometry uniqueness …, with higher values indicating structurally distinctive neighbourhoods"
  — "structurally distinctive splats increase retention evidence" (u feeds A).

A reading *preserves* the paper's direction when, over a real scene's voxels, its statistic rises
with the matching homogeneity (ℓ, s: Spearman ρ > 0) or falls with it (u: ρ < 0), and *reverses* it
otherwise. Homogeneity is measured here without the HSFH descriptor, on the same neighbourhoods
N(j) (the FPFH search of :mod:`methods.betadesc.hsfh`):

* **geometric homogeneity** H_geo(j) = −surface variation of the voxel points of N(j):
  λ₀ / (λ₀ + λ₁ + λ₂), λ₀ the smallest eigenvalue of their covariance (Pauly et al. 2002: 0 on a
  plane, 1/3 for an isotropic blob); NaN below 3 points;
* **normal coherence** C(j) = mean over k ∈ N(j) of |n_j · n_k|, the pipeline's voxel normals
  (:func:`methods.betadesc.normals.voxel_normals`): a second, descriptor-side measure of geometric
  homogeneity, reported beside H_geo as a check (the verdict reads H_geo);
* **appearance homogeneity** H_app(j) = −Σ_rgb var(c) over the splats of N(j), c = the base colour
  clip(0.5 + SH_C0·f_dc, 0, 1) of each splat (every splat of every voxel of N(j) counted once per voxel).

:func:`directions` returns ρ of every reading of ℓ, s and u with both homogeneities and the verdict
against the matching one (H_geo for ℓ and u, H_app for s); ``harness bench reading directions``
writes them for the real scenes (``results/reading/directions.md``), and the readings' docstrings
in :mod:`methods.betadesc.statistics` quote those numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from harness.core.scene import SH_C0, GaussianScene
from methods.betadesc.hsfh import HSFH, compute_hsfh
from methods.betadesc.normals import voxel_normals
from methods.betadesc.statistics import ELL_READINGS, S_READINGS, U_READINGS, voxel_statistic

#: statistic -> (the homogeneity it is judged against, the sign of ρ the paper's words give)
PAPER_DIRECTION = {"ell": ("geo", +1), "s": ("app", +1), "u": ("geo", -1)}
#: what the readings' docstrings declare (measured on luigi, grape-small, bonsai-7k-mini; a test
#: re-measures it so the documentation cannot drift from the code)
PRESERVES = {("ell", "nbhd-std"): False, ("ell", "dims-std"): False, ("ell", "dims-peak"): True,
             ("s", "nbhd-var"): True, ("s", "dims-var"): False, ("s", "dims-peak"): True,
             ("u", "dispersion"): True, ("u", "std-geo"): False, ("u", "std-hsfh"): False,
             ("u", "spread-hsfh"): True}


@dataclass(frozen=True)
class Direction:
    statistic: str        # ell, s, u
    reading: str          # the value of ell_def / s_def / u_def
    rho_geo: float        # Spearman ρ with H_geo (NaN voxels left out)
    rho_app: float        # Spearman ρ with H_app
    rho_coherence: float  # Spearman ρ with the normal coherence C (a check on rho_geo)
    preserves: bool       # ρ against the matching homogeneity has the paper's sign

    @property
    def rho(self) -> float:
        return self.rho_geo if PAPER_DIRECTION[self.statistic][0] == "geo" else self.rho_app


def geometric_homogeneity(desc: HSFH) -> np.ndarray:
    """−λ₀/(λ₀+λ₁+λ₂) of the voxel points of each N(j) (NaN below 3 points or a degenerate spread)."""
    adj = desc.adjacency()
    p = desc.grid.points
    n = np.asarray(adj.sum(axis=1)).ravel()
    mean = (adj @ p) / n[:, None]
    outer = (p[:, :, None] * p[:, None, :]).reshape(len(p), 9)
    cov = ((adj @ outer) / n[:, None]).reshape(-1, 3, 3) - mean[:, :, None] * mean[:, None, :]
    lam = np.clip(np.linalg.eigvalsh(cov), 0.0, None)
    total = lam.sum(axis=1)
    ok = (n >= 3) & (total > 1e-12)
    return np.where(ok, -lam[:, 0] / np.where(ok, total, 1.0), np.nan)


def normal_coherence(scene: GaussianScene, desc: HSFH, radius_voxels: float) -> np.ndarray:
    """Mean |n_j · n_k| over k ∈ N(j) of the voxel normals."""
    n = voxel_normals(desc.grid, scene.quats, scene.scales_log, radius_voxels)
    adj = desc.adjacency().tocoo()
    dots = np.abs(np.einsum("ij,ij->i", n[adj.row], n[adj.col]))
    return np.bincount(adj.row, dots, desc.grid.m) / np.bincount(adj.row, minlength=desc.grid.m)


def appearance_homogeneity(scene: GaussianScene, desc: HSFH) -> np.ndarray:
    """−Σ_rgb var(base colour) over the splats of each N(j)."""
    c = np.clip(0.5 + SH_C0 * scene.sh_dc.astype(np.float64), 0.0, 1.0)
    grid = desc.grid
    sums = np.zeros((grid.m, 6))
    np.add.at(sums, grid.splat_voxel, np.concatenate([c, c * c], axis=1))
    adj = desc.adjacency()
    tot = adj @ sums
    members = adj @ grid.counts
    mean = tot[:, :3] / members[:, None]
    var = np.maximum(tot[:, 3:] / members[:, None] - mean * mean, 0.0)
    return -var.sum(axis=1)


def _rho(x: np.ndarray, h: np.ndarray) -> float:
    ok = np.isfinite(h) & np.isfinite(x)
    if ok.sum() < 3 or np.ptp(x[ok]) == 0 or np.ptp(h[ok]) == 0:
        return float("nan")
    return float(stats.spearmanr(x[ok], h[ok]).statistic)


def directions(scene: GaussianScene, *, voxel: float = 0.01, radius_voxels: float = 5.0, max_nn: int = 100,
               colour_bins: int = 8, norm: str = "minmax") -> list[Direction]:
    """ρ of every reading of ℓ, s, u (as the pipeline computes them, normalised by ``norm``) with
    H_geo and H_app over the voxels of ``scene``; the verdict against the paper's direction."""
    desc = compute_hsfh(scene, voxel, radius_voxels, max_nn, colour_bins)
    h = {"geo": geometric_homogeneity(desc), "app": appearance_homogeneity(scene, desc),
         "coherence": normal_coherence(scene, desc, radius_voxels)}
    out = []
    for stat, readings in (("ell", ELL_READINGS), ("s", S_READINGS), ("u", U_READINGS)):
        against, sign = PAPER_DIRECTION[stat]
        for reading in readings:
            x = voxel_statistic(desc, stat, reading, norm)
            rg, ra = _rho(x, h["geo"]), _rho(x, h["app"])
            rho = rg if against == "geo" else ra
            out.append(Direction(stat, reading, rg, ra, _rho(x, h["coherence"]),
                                 bool(np.isfinite(rho) and np.sign(rho) == sign)))
    return out
