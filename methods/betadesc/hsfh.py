"""HSFH: the per-voxel splat descriptor of the paper's §3.1 (geometry + SH appearance).

For every occupied voxel j (see :mod:`methods.betadesc.grid`) with neighbourhood N(j) = the
``max_nn`` nearest voxel points within ``radius_voxels`` voxels (j included; the FPFH search):

* **geometric block** ``g_j`` (33): FPFH of the voxel points (MST-oriented normals from the
  members' shortest scale axes, :mod:`methods.betadesc.backend`), each of the three 11-bin angle
  histograms (α, φ, θ) normalised to sum 1; all-zero where a voxel has no neighbour (FPFH undefined).
* **spectrum block** ``f̄_j`` (L+1): per splat the relative SH band power
  ``f_ℓ = P_ℓ / Σ_ℓ' P_ℓ'`` with ``P_ℓ = Σ_m ‖c_ℓm‖²`` (RGB channels summed) for the bands the
  scene has (degree 0 → P₀ only, f₀ ≡ 1), averaged over all splats of N(j); the block sums to 1.
  Its per-component variance over those splats, ``var f_j``, is kept for the statistics.
* **colour block** ``h_j`` (3·B): per channel a B-bin histogram of the base colours
  ``clip(0.5 + SH_C0·f_dc, 0, 1)`` of all splats of N(j), each channel normalised to sum 1.

All neighbourhood sums are exact (integer-valued) so the descriptor is independent of splat order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse

from harness.core.scene import SH_C0, GaussianScene
from methods.betadesc import backend
from methods.betadesc.grid import FIXED, SplatGrid, build_grid
from methods.betadesc.normals import voxel_normals

BINS_PER_ANGLE = 11


@dataclass(frozen=True)
class HSFH:
    grid: SplatGrid
    geometric: np.ndarray   # (M, 33) per-angle normalised FPFH
    spectrum: np.ndarray    # (M, L+1) neighbourhood mean of relative band powers
    spectrum_var: np.ndarray  # (M, L+1) their neighbourhood variance
    colour: np.ndarray      # (M, 3, B) neighbourhood colour histograms (fractions)
    indptr: np.ndarray      # CSR neighbourhood N(j)
    indices: np.ndarray

    def descriptor(self) -> np.ndarray:
        """The concatenated HSFH vector per voxel: [g (33) | f̄ (L+1) | h (3·B)]."""
        return np.concatenate([self.geometric, self.spectrum, self.colour.reshape(len(self.colour), -1)], axis=1)

    def adjacency(self) -> sparse.csr_matrix:
        m = self.grid.m
        data = np.ones(len(self.indices))
        return sparse.csr_matrix((data, self.indices, self.indptr), shape=(m, m))


def normalise_fpfh(fpfh: np.ndarray) -> np.ndarray:
    """Each 11-bin angle histogram divided by its sum (rows with an empty histogram stay 0)."""
    blocks = fpfh.reshape(len(fpfh), 3, BINS_PER_ANGLE)
    total = blocks.sum(axis=2, keepdims=True)
    out = np.divide(blocks, total, out=np.zeros_like(blocks), where=total > 0)
    return out.reshape(len(fpfh), 3 * BINS_PER_ANGLE)


def band_fractions(scene: GaussianScene) -> np.ndarray:
    """Relative SH band power f_ℓ = P_ℓ / Σ P per splat (N, L+1); all-zero SH gives f = 0."""
    power = [np.einsum("ij,ij->i", scene.sh_dc, scene.sh_dc, dtype=np.float64)]
    start = 0
    for band in range(1, scene.sh_degree + 1):
        width = 2 * band + 1
        c = scene.sh_rest[:, start:start + width].astype(np.float64)
        power.append(np.einsum("ikc,ikc->i", c, c))
        start += width
    p = np.stack(power, axis=1)
    total = p.sum(axis=1, keepdims=True)
    return np.divide(p, total, out=np.zeros_like(p), where=total > 0)


def colour_bins(scene: GaussianScene, bins: int) -> np.ndarray:
    """Bin index (N, 3) of each channel of the base colour clip(0.5 + SH_C0·f_dc, 0, 1)."""
    c = np.clip(0.5 + SH_C0 * scene.sh_dc.astype(np.float64), 0.0, 1.0)
    return np.minimum((c * bins).astype(np.int64), bins - 1)


def compute_hsfh(scene: GaussianScene, voxel: float, radius_voxels: float, max_nn: int,
                 bins: int, grid: SplatGrid | None = None) -> HSFH:
    """HSFH descriptors of every occupied voxel of ``scene`` (see the module docstring)."""
    if not (radius_voxels > 0 and max_nn >= 1 and bins >= 1):
        raise ValueError(f"need radius_voxels > 0, max_nn >= 1 and colour_bins >= 1; got "
                         f"{radius_voxels}, {max_nn}, {bins}")
    grid = build_grid(scene.means, voxel) if grid is None else grid
    m = grid.m
    normals = voxel_normals(grid, scene.quats, scene.scales_log, radius_voxels)
    nbh = backend.neighbourhood(grid.points, radius_voxels, max_nn)
    geometric = normalise_fpfh(backend.fpfh(grid.points, normals, nbh))
    indptr, indices = backend.csr(nbh)
    adj = sparse.csr_matrix((np.ones(len(indices)), indices, indptr), shape=(m, m))

    # Spectrum moments over N(j): exact integer sums of f and f² (both in [0, 1]).
    frac = band_fractions(scene)
    moments = grid.voxel_sum(np.concatenate([frac, frac * frac], axis=1))
    total = adj @ np.concatenate([moments, grid.counts[:, None]], axis=1)
    members = total[:, -1:]
    nb = frac.shape[1]
    mean = total[:, :nb] / FIXED / members
    var = np.maximum(total[:, nb:2 * nb] / FIXED / members - mean * mean, 0.0)

    # Colour histograms over N(j): integer counts per (voxel, channel, bin).
    cb = colour_bins(scene, bins)
    flat = (grid.splat_voxel[:, None] * 3 + np.arange(3)) * bins + cb
    counts = np.bincount(flat.ravel(), minlength=m * 3 * bins).reshape(m, 3 * bins).astype(np.float64)
    colour = (adj @ counts).reshape(m, 3, bins) / members[:, :, None]
    return HSFH(grid=grid, geometric=geometric, spectrum=mean, spectrum_var=var, colour=colour,
                indptr=indptr, indices=indices)
