"""Cheap sanity baselines: rank by opacity, by opacity-weighted volume, or at random.

* ``opacity``: score = sigmoid(opacity_logit).
* ``volume``:  score = (s_x·s_y·s_z)·opacity with s = exp(scales_log) — big, opaque splats are kept.
  Computed in log space (Σ log s + log o) so that tiny or huge scales cannot under/overflow; the
  ranking is identical to the product's.
* ``random``:  score ~ U(0, 1) from ``numpy.random.default_rng(seed)`` with the run's seed; deterministic in it.
"""

from __future__ import annotations

import numpy as np

from harness.core.scene import GaussianScene
from methods.registry import PruneContext, register_pruner


def _log_opacity(logit: np.ndarray) -> np.ndarray:
    """log(sigmoid(x)) = −log(1 + e^{−x}), stable for any x."""
    return -np.logaddexp(0.0, -logit.astype(np.float64))


@register_pruner("opacity", label="Opacity", group="baseline")
def opacity_score(scene: GaussianScene, ctx: PruneContext) -> np.ndarray:
    """Keep the most opaque splats: score = sigmoid(opacity)."""
    return np.exp(_log_opacity(scene.opacity_logit))


@register_pruner("volume", label="Volume", group="baseline")
def volume_score(scene: GaussianScene, ctx: PruneContext) -> np.ndarray:
    """Keep big, opaque splats: score = log(s_x·s_y·s_z·opacity) (same ranking as the product)."""
    return scene.scales_log.astype(np.float64).sum(axis=1) + _log_opacity(scene.opacity_logit)


@register_pruner("random", label="Random", group="baseline")
def random_score(scene: GaussianScene, ctx: PruneContext) -> np.ndarray:
    """Uniform random scores, deterministic in the run's seed."""
    return np.random.default_rng(ctx.seed).random(len(scene))
