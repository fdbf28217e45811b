"""One vocabulary for how much is pruned: a **ratio** r ∈ [0, 1] is the fraction of splats removed;
a keep fraction k is the fraction kept, r = 1 − k. Everything stores and compares ratios.

Ratios are canonicalised to 9 decimals (:func:`canonical`) when they enter (configs, flags), so
``keep: [0.7]`` and ``ratios: [0.3]`` are the same ratio bit for bit, and two stored ratios are
equal exactly when :func:`same` says so (``|a − b| ≤ TOLERANCE``, half a unit of the last decimal).
"""

from __future__ import annotations

import math

DECIMALS = 9
TOLERANCE = 0.5 * 10.0 ** -DECIMALS


def canonical(ratio: float) -> float:
    """``ratio`` rounded to :data:`DECIMALS` decimals; ValueError outside [0, 1] or not finite."""
    r = float(ratio)
    if not (math.isfinite(r) and 0.0 <= r <= 1.0):
        raise ValueError(f"a pruning ratio must be a number in [0, 1], got {ratio!r}")
    return round(r, DECIMALS)


def from_keep(keep: float) -> float:
    """The ratio of a keep fraction: 1 − keep, canonical."""
    k = float(keep)
    if not (math.isfinite(k) and 0.0 <= k <= 1.0):
        raise ValueError(f"a keep fraction must be a number in [0, 1], got {keep!r}")
    return canonical(1.0 - k)


def to_keep(ratio: float) -> float:
    """The keep fraction of a ratio: 1 − ratio, canonical."""
    return canonical(1.0 - canonical(ratio))


def key(ratio: float) -> float:
    """The key under which results of ``ratio`` are grouped and looked up: its value to
    :data:`DECIMALS` decimals (no range check: stored results are read as they are)."""
    return round(float(ratio), DECIMALS)


def same(a: float, b: float) -> bool:
    """Are two (canonical) ratios the same?"""
    return abs(float(a) - float(b)) <= TOLERANCE


def merge(ratios=(), keeps=()) -> tuple[float, ...]:
    """Sorted union of ratios and the ratios of keep fractions."""
    return tuple(sorted({canonical(r) for r in ratios} | {from_keep(k) for k in keeps}))


def percent(ratio: float) -> str:
    """``30%`` — for table labels."""
    return f"{round(100 * float(ratio))}%"
