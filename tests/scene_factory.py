"""Small random :class:`GaussianScene` objects for tests (shared by every test module).

Values are drawn to look like a trained scene: centres ~ N(0, 1), log-scales ~ N(-4, 0.5)
(std-devs around 2 % of the unit cube), random non-normalised quaternions (never zero-norm),
opacity logits ~ N(0, 2), DC ~ N(0, 1), higher SH ~ N(0, 0.1). All float32, deterministic in ``seed``.
"""

from __future__ import annotations

import numpy as np

from harness.core.scene import SH_REST_COUNT, GaussianScene


def random_scene(n: int, sh_degree: int = 0, seed: int = 0, extra: bool = False) -> GaussianScene:
    """A scene of ``n`` splats with SH degree ``sh_degree`` (0..3).

    ``extra=True`` adds the INRIA normal properties ``nx, ny, nz`` (random unit vectors here, so a
    test can tell them apart from zeros) as extra float32 arrays, in that order.
    """
    rng = np.random.default_rng(seed)
    k = SH_REST_COUNT[sh_degree]
    quats = rng.normal(size=(n, 4))
    quats[np.linalg.norm(quats, axis=1) < 1e-3] = (1.0, 0.0, 0.0, 0.0)
    extras = {}
    if extra:
        normals = rng.normal(size=(n, 3))
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        extras = {name: normals[:, i].astype(np.float32) for i, name in enumerate(("nx", "ny", "nz"))}
    return GaussianScene.from_arrays(
        means=rng.normal(size=(n, 3)),
        scales_log=rng.normal(-4.0, 0.5, size=(n, 3)),
        quats=quats,
        opacity_logit=rng.normal(0.0, 2.0, size=n),
        sh_dc=rng.normal(size=(n, 3)),
        sh_rest=rng.normal(0.0, 0.1, size=(n, k, 3)),
        extra=extras,
    )
