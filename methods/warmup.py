"""Compile every numba kernel once, at set-up (``python -m methods.warmup``), so that the first
``harness prune`` on a fresh install costs what the second does.

The kernels are ``@njit(cache=True)``: numba writes the machine code next to the sources
(``__pycache__/*.nbi|nbc``) and later processes load it. A cache entry is per argument types, so the
warm-up runs the real code paths on a small synthetic scene built like a loaded one (float32 arrays,
SH degree 0 and 3): the four BetaDescPrune variants, and the pixel-pair rasterizer of the camera-aware
pruners (forward, statistics and gradient).
"""

from __future__ import annotations

import time

import numpy as np


def synthetic_scene(n: int = 3000, sh_degree: int = 3, seed: int = 0):
    from harness.core.scene import SH_REST_COUNT, GaussianScene

    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    return GaussianScene.from_arrays(
        means=rng.normal(size=(n, 3)), scales_log=rng.normal(-3.0, 0.5, (n, 3)), quats=q,
        opacity_logit=rng.normal(0.0, 2.0, n), sh_dc=rng.normal(0.0, 0.5, (n, 3)),
        sh_rest=rng.normal(0.0, 0.1, (n, SH_REST_COUNT[sh_degree], 3)))


def compile_kernels() -> dict[str, float]:
    """Run every kernel once; returns seconds per part (compilation dominates on a fresh install)."""
    import torch

    from harness.core.cameras import Camera
    from methods.registry import PruneContext, get_pruner
    from renderers.pixel_pairs import build_pairs, composite, render_pairs
    from renderers.projection import SplatTensors, project_gaussians

    seconds = {}
    for degree in (0, 3):
        scene = synthetic_scene(sh_degree=degree)
        for name in ("betadesc", "betadesc-nodesc", "betadesc-nobeta", "betadesc-nodesc-nobeta"):
            t0 = time.perf_counter()
            get_pruner(name).score(scene, PruneContext())
            seconds[f"{name} (SH {degree})"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    cam = Camera.look_at((0.0, 0.0, -6.0), (0.0, 0.0, 0.0), width=48, height=32)
    with torch.no_grad():
        proj = project_gaussians(SplatTensors.from_scene(synthetic_scene(500, 0)), cam)
    pairs = build_pairs(proj)
    composite(pairs, early_stop=True, stats=True)
    op = torch.tensor(pairs.opacities, requires_grad=True)
    render_pairs(pairs, op).sum().backward()
    seconds["pixel pairs"] = time.perf_counter() - t0
    return seconds


if __name__ == "__main__":
    t0 = time.perf_counter()
    compile_kernels()
    print(f"numba kernels compiled and cached in {time.perf_counter() - t0:.1f} s")
