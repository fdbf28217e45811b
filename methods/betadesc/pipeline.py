"""BetaDescPrune end to end: statistics → Eq. 4 evidence → score, for the method and its ablations.

Stages (timed when a caller wraps the run in :func:`harness.core.timing.record_stages`):
``voxels`` grid · ``descriptors`` normals + FPFH + neighbourhood appearance · ``statistics``
ℓ, s, u (+ o) · ``interpolate`` voxel → splat · ``views`` optional camera features ·
``scores`` evidence and ranking score.

Every reading choice comes from ``params`` (:mod:`methods.betadesc.params`); the ablations read the
same attributes, so they share the full method's reading of everything they keep:

* without descriptors, s, ℓ, u come from each splat's own parameters (w = 1;
  :mod:`methods.betadesc.nodesc`: ``nodesc_def`` ``splat-params`` or ``param-stats``);
  ``"opacity-only"`` drops the s, ℓ, u terms of Eq. 4, so its ranking is a monotone function of
  opacity alone (the ``opacity`` baseline's twin);
* without Beta, the score is the net evidence A − B of the same (A, B) (the prior cancels).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.core.scene import GaussianScene
from harness.core.timing import stage
from methods.betadesc import evidence as ev
from methods.betadesc.grid import build_grid
from methods.betadesc.hsfh import compute_hsfh
from methods.betadesc.interpolate import interpolate_to_splats
from methods.betadesc.nodesc import splat_statistics
from methods.betadesc.params import BetaParams
from methods.betadesc.scores import beta_score
from methods.betadesc.statistics import opacity_statistic, voxel_statistics


@dataclass(frozen=True)
class Components:
    """Every per-splat quantity of one run (for diagnostics): statistics, evidence and the score.

    ``voxel`` is each splat's voxel index (−1 without descriptors)."""

    s: np.ndarray
    ell: np.ndarray
    o: np.ndarray
    u: np.ndarray
    w: np.ndarray
    a: np.ndarray
    b: np.ndarray
    score: np.ndarray
    voxel: np.ndarray


def _nodesc_opacity_only(params) -> bool:
    return params.nodesc_def == "opacity-only"


def statistics(scene: GaussianScene, params, descriptors: bool) -> tuple[np.ndarray, ...]:
    """Per-splat (s, ℓ, o, u, w, voxel index): from HSFH neighbourhoods, or per splat (w = 1)."""
    n = len(scene)
    with stage("statistics"):
        o = opacity_statistic(scene, params.o_norm)
    if not descriptors:
        with stage("statistics"):
            if _nodesc_opacity_only(params):
                ell = s = u = np.zeros(n)
            else:
                ell, s, u = splat_statistics(scene, params.nodesc_def, params.stat_norm).T
        return s, ell, o, u, np.ones(n), np.full(n, -1, dtype=np.int64)
    with stage("voxels"):
        grid = build_grid(scene.means, params.voxel)
    with stage("descriptors"):
        desc = compute_hsfh(scene, params.voxel, params.radius_voxels,
                            params.max_nn, params.colour_bins, grid=grid)
    with stage("statistics"):
        per_voxel = voxel_statistics(desc, ell_def=params.ell_def, s_def=params.s_def,
                                     u_def=params.u_def, norm=params.stat_norm)
    with stage("interpolate"):
        per_splat, w = interpolate_to_splats(grid, per_voxel, kernel=params.kernel, w_mode=params.w_mode)
    ell, s, u = per_splat.T
    return s, ell, o, u, w, grid.splat_voxel


def coefficients(params, descriptors: bool) -> ev.Coefficients:
    c = ev.preset(params.preset, params.coeff_order)
    return ev.opacity_only(c) if not descriptors and _nodesc_opacity_only(params) else c


def components(scene: GaussianScene, params, cameras=None, *, descriptors: bool = True,
               beta: bool = True, retention: np.ndarray | None = None) -> Components:
    """Every per-splat quantity of the run (:class:`Components`); ``score`` is what :func:`run` returns.
    ``retention`` (N,): extra retention evidence added to A (``betadesc-vr``: :mod:`methods.betadesc.vr`)."""
    s, ell, o, u, w, voxel = statistics(scene, params, descriptors)
    edge, edge_weight = 0.0, 0.0
    if cameras and params.view_weight > 0:
        from methods.betadesc.view_aware import edge_proxy

        with stage("views"):
            edge, edge_weight = edge_proxy(scene, cameras, o), params.view_weight
    # the Beta-free ablations have no prior (A − B does not depend on it): the declared default
    prior = params.prior if isinstance(params, BetaParams) else BetaParams().prior
    with stage("scores"):
        a, b = ev.evidence(s, ell, o, u, w, coefficients(params, descriptors), prior=prior,
                           edge=edge, edge_weight=edge_weight)
        if retention is not None:
            a = a + retention
        if not beta:
            score = a - b
        else:
            score = beta_score(a, b, params.score, gamma=params.gamma, z=params.z, q=params.q)
    return Components(s=s, ell=ell, o=o, u=u, w=np.asarray(w, np.float64), a=a, b=b, score=score, voxel=voxel)


def run(scene: GaussianScene, params, cameras=None, *, descriptors: bool = True,
        beta: bool = True) -> np.ndarray:
    """Scores (N,) float64, higher = keep. ``beta=False`` ranks by net evidence A − B."""
    if len(scene) == 0:
        return np.zeros(0)
    return components(scene, params, cameras, descriptors=descriptors, beta=beta).score
