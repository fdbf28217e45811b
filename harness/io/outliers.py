"""Outliers that make a quantising writer move the other splats: found, and said in one warning.

compressed.ply stores centres per chunk of 256 splats in Morton order over the chunk's range, spz
with as many fractional bits as the farthest centre leaves, SOG over the log-transformed bounding
box. A splat far from the others widens that range for everyone it shares it with: one splat at
x = 1e30 in a 100-splat compressed.ply puts the other 99 in its chunk at the chunk's minimum.

The scene's *core* is the box spanned, per axis, by the 1st and 99th percentiles of the centres
(nearest rank); its diagonal ``E`` is the scene's extent. Writing moves a core splat "because of
outliers" when it moves it by more than

    bound = max(0.1 % · E, 2 · (the largest move of writing the core alone), 4 float32 steps of the core)

— beyond what the format gives the same splats without the others, and beyond 0.1 % of the
extent. Without splats outside the core this cannot happen, and a scene whose bounding box is at
most twice the core's is not examined further (no format here moves a splat by 0.1 % of ``E``
then).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

RELATIVE_BOUND = 1e-3
_PERCENTILES = (1.0, 99.0)


def core_box(means: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) corners of the box of the 1st..99th percentile centres, per axis."""
    lo, hi = np.percentile(np.asarray(means, np.float64), _PERCENTILES, axis=0, method="nearest")
    return lo, hi


def displacement_warning(path, means: np.ndarray, position_error: Callable[[np.ndarray], np.ndarray]) -> str | None:
    """One line when outliers made the writer move core splats beyond the bound (module docstring)."""
    means = np.asarray(means, np.float64)
    if len(means) < 2:
        return None
    lo, hi = core_box(means)
    extent = float(np.linalg.norm(hi - lo))
    full = float(np.linalg.norm(means.max(0) - means.min(0)))
    if full <= 2.0 * extent:
        return None
    inside = np.all((means >= lo) & (means <= hi), axis=1)
    moved = position_error(means)[inside]
    alone = float(position_error(means[inside]).max(initial=0.0))
    ulp = 4.0 * float(np.spacing(np.float32(np.abs(means[inside]).max(initial=0.0))))
    bound = max(RELATIVE_BOUND * extent, 2.0 * alone, ulp)
    over = moved > bound
    if not over.any():
        return None
    away = np.linalg.norm(np.maximum(lo - means, 0.0) + np.maximum(means - hi, 0.0), axis=1)
    far = int(np.argmax(away))
    return (f"{path}: {int(over.sum()):,} splats are stored up to {float(moved.max()):.3g} units from where they "
            f"were, more than {bound:.3g} (0.1 % of the scene's extent {extent:.3g}), because a splat at "
            f"({', '.join(f'{v:.3g}' for v in means[far])}) lies {float(away[far]):.3g} units outside the box of "
            "98 % of the others and the format's range must hold it; remove such splats first, or write .ply "
            "(exact positions)")
