"""BetaDescPrune end to end: statistics → Eq. 6 evidence → score, for the method and its ablations.

Stages (timed when a caller wraps the run in :func:`record_stages`):
``voxels`` grid · ``descriptors`` normals + FPFH + neighbourhood appearance · ``statistics``
ℓ, s, u (+ o) · ``interpolate`` voxel → splat · ``views`` optional camera features ·
``scores`` evidence and ranking score.
"""

from __future__ import annotations

import contextvars
import time
from contextlib import contextmanager

import numpy as np

from harness.core.scene import GaussianScene
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

_STAGES: contextvars.ContextVar[tuple | None] = contextvars.ContextVar("betadesc_stages", default=None)


@contextmanager
def record_stages(clock=time.perf_counter):
    """``with record_stages() as t: score(...)`` fills ``t`` with seconds per stage, measured by
    ``clock`` (wall time by default; ``time.process_time`` gives CPU seconds of all threads)."""
    times: dict[str, float] = {}
    token = _STAGES.set((times, clock))
    try:
        yield times
    finally:
        _STAGES.reset(token)


@contextmanager
def _stage(name: str):
    active = _STAGES.get()
    t0 = active[1]() if active else 0.0
    try:
        yield
    finally:
        if active:
            times, clock = active
            times[name] = times.get(name, 0.0) + clock() - t0


def statistics(scene: GaussianScene, params: dict, descriptors: bool) -> tuple[np.ndarray, ...]:
    """Per-splat (s, ℓ, o, u, w): from HSFH neighbourhoods, or per splat (w = 1) without them."""
    with _stage("statistics"):
        o = opacity_statistic(scene)
    if not descriptors:
        with _stage("statistics"):
            ell, s, u = splat_statistics(scene).T
        return s, ell, o, u, np.ones(len(scene))
    with _stage("voxels"):
        grid = build_grid(scene.means, float(params["voxel"]))
    with _stage("descriptors"):
        desc = compute_hsfh(scene, float(params["voxel"]), float(params["radius_voxels"]),
                            int(params["max_nn"]), int(params["colour_bins"]), grid=grid)
    with _stage("statistics"):
        per_voxel = voxel_statistics(desc)
    with _stage("interpolate"):
        per_splat, w = interpolate_to_splats(grid, per_voxel)
    ell, s, u = per_splat.T
    return s, ell, o, u, w


def posterior(scene: GaussianScene, params: dict, cameras, descriptors: bool,
              prior: float) -> tuple[np.ndarray, np.ndarray]:
    """Beta parameters (A, B) per splat (Eq. 6, plus the edge proxy when cameras are given)."""
    s, ell, o, u, w = statistics(scene, params, descriptors)
    edge, edge_weight = 0.0, 0.0
    if cameras and float(params["view_weight"]) > 0:
        from methods.betadesc.view_aware import edge_proxy

        with _stage("views"):
            edge, edge_weight = edge_proxy(scene, cameras, o), float(params["view_weight"])
    with _stage("scores"):
        return ev.evidence(s, ell, o, u, w, ev.preset(str(params["preset"])), prior=prior,
                           edge=edge, edge_weight=edge_weight)


def run(scene: GaussianScene, params: dict, cameras=None, *, descriptors: bool = True,
        beta: bool = True) -> np.ndarray:
    """Scores (N,) float64, higher = keep. ``beta=False`` ranks by net evidence A − B."""
    if len(scene) == 0:
        return np.zeros(0)
    prior = float(params.get("prior", 1.0))
    a, b = posterior(scene, params, cameras, descriptors, prior)
    with _stage("scores"):
        if not beta:
            return a - b
        return beta_score(a, b, str(params["score"]), gamma=float(params["gamma"]),
                          z=float(params["z"]), q=float(params["q"]))
