"""BetaDescPrune end to end: statistics → Eq. 6 evidence → score, for the method and its ablations.

Stages (timed when a caller wraps the run in :func:`harness.core.timing.record_stages`):
``voxels`` grid · ``descriptors`` normals + FPFH + neighbourhood appearance · ``statistics``
ℓ, s, u (+ o) · ``interpolate`` voxel → splat · ``views`` optional camera features ·
``scores`` evidence and ranking score.
"""

from __future__ import annotations

import numpy as np

from harness.core.scene import GaussianScene
from harness.core.timing import stage
from methods.betadesc import evidence as ev
from methods.betadesc.grid import build_grid
from methods.betadesc.hsfh import compute_hsfh
from methods.betadesc.interpolate import interpolate_to_splats
from methods.betadesc.scores import beta_score
from methods.betadesc.statistics import (
    opacity_statistic,
    splat_statistics,
    voxel_statistics,
)


def statistics(scene: GaussianScene, params, descriptors: bool) -> tuple[np.ndarray, ...]:
    """Per-splat (s, ℓ, o, u, w): from HSFH neighbourhoods, or per splat (w = 1) without them."""
    with stage("statistics"):
        o = opacity_statistic(scene)
    if not descriptors:
        with stage("statistics"):
            ell, s, u = splat_statistics(scene).T
        return s, ell, o, u, np.ones(len(scene))
    with stage("voxels"):
        grid = build_grid(scene.means, params.voxel)
    with stage("descriptors"):
        desc = compute_hsfh(scene, params.voxel, params.radius_voxels,
                            params.max_nn, params.colour_bins, grid=grid)
    with stage("statistics"):
        per_voxel = voxel_statistics(desc)
    with stage("interpolate"):
        per_splat, w = interpolate_to_splats(grid, per_voxel)
    ell, s, u = per_splat.T
    return s, ell, o, u, w


def posterior(scene: GaussianScene, params, cameras, descriptors: bool,
              prior: float) -> tuple[np.ndarray, np.ndarray]:
    """Beta parameters (A, B) per splat (Eq. 6, plus the edge proxy when cameras are given)."""
    s, ell, o, u, w = statistics(scene, params, descriptors)
    edge, edge_weight = 0.0, 0.0
    if cameras and params.view_weight > 0:
        from methods.betadesc.view_aware import edge_proxy

        with stage("views"):
            edge, edge_weight = edge_proxy(scene, cameras, o), params.view_weight
    with stage("scores"):
        return ev.evidence(s, ell, o, u, w, ev.preset(params.preset), prior=prior,
                           edge=edge, edge_weight=edge_weight)


def run(scene: GaussianScene, params, cameras=None, *, descriptors: bool = True,
        beta: bool = True) -> np.ndarray:
    """Scores (N,) float64, higher = keep. ``beta=False`` ranks by net evidence A − B."""
    if len(scene) == 0:
        return np.zeros(0)
    prior = getattr(params, "prior", 1.0)  # the Beta-free ablations keep the default prior
    a, b = posterior(scene, params, cameras, descriptors, prior)
    with stage("scores"):
        if not beta:
            return a - b
        return beta_score(a, b, params.score, gamma=params.gamma, z=params.z, q=params.q)
