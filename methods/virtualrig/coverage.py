"""Where to stand in a room: the free-space positions whose views see the most content.

On the occupancy grid of :mod:`.shape` (cell units), a candidate camera at position p looking at the
subject sees an occupied cell c when c lies inside its view cone (half-angle fov/2 + half a cell's
angular size) and the segment from p to c, marched in half-cell steps, meets no occupied cell before
the last cell in front of c. A cell's *value* is its opacity mass. Positions are chosen greedily,
each time the candidate with the largest gain

    gain(p) = Σ_{c seen from p} mass_c · ½^{n_c}

where n_c is how many chosen views already see c (diminishing returns: a cell seen once is worth
half as much again, so the views spread over the content instead of piling onto its best side).
Only positions that see the subject itself are candidates (:func:`sees_point`: the segment to it
meets no occupied cell but the subject's own): a position under the table top the subject stands
on, or behind a wall, is not a place a capture of it is taken from. Nothing about which way is up
is assumed. Deterministic: ties go to the lower candidate index.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

STEP = 0.5  # march step, cells
END_GAP = 1.0  # cells before the target where the march stops (the target's own surface)


@nb.njit(cache=True)
def _seen(occupied, starts, forwards, cos_half, targets, end_gap):
    """(S, T) bool: target point t visible from start s: inside its cone and nothing occupied on the
    way until ``end_gap`` cells before it (module docstring)."""
    nx, ny, nz = occupied.shape
    out = np.zeros((starts.shape[0], targets.shape[0]), np.bool_)
    for s in range(starts.shape[0]):
        px, py, pz = starts[s, 0], starts[s, 1], starts[s, 2]
        for t in range(targets.shape[0]):
            dx, dy, dz = targets[t, 0] - px, targets[t, 1] - py, targets[t, 2] - pz
            dist = math.sqrt(dx * dx + dy * dy + dz * dz)
            if dist < 1e-9:
                continue
            if (dx * forwards[s, 0] + dy * forwards[s, 1] + dz * forwards[s, 2]) / dist < cos_half:
                continue
            ux, uy, uz = dx / dist, dy / dist, dz / dist
            free = True
            d = STEP
            while d < dist - end_gap:
                ix, iy, iz = int(math.floor(px + d * ux)), int(math.floor(py + d * uy)), int(math.floor(pz + d * uz))
                if 0 <= ix < nx and 0 <= iy < ny and 0 <= iz < nz and occupied[ix, iy, iz]:
                    free = False
                    break
                d += STEP
            out[s, t] = free
    return out


def visibility(occupied: np.ndarray, starts: np.ndarray, forwards: np.ndarray, fov_deg: float) -> np.ndarray:
    """(S, C) bool: which occupied cells (``np.argwhere(occupied)`` order) each start (grid units)
    looking along its forward (unit) sees."""
    targets = np.argwhere(occupied).astype(np.float64) + 0.5
    cos_half = math.cos(min(math.radians(fov_deg) / 2.0 + math.radians(2.0), math.pi))
    return _seen(occupied, np.ascontiguousarray(starts, np.float64), np.ascontiguousarray(forwards, np.float64),
                 cos_half, targets, END_GAP)


@nb.njit(cache=True)
def _sees_subject(occupied, subject, starts, point):
    nx, ny, nz = occupied.shape
    out = np.zeros(starts.shape[0], np.bool_)
    for s in range(starts.shape[0]):
        dx, dy, dz = point[0] - starts[s, 0], point[1] - starts[s, 1], point[2] - starts[s, 2]
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        out[s] = True
        d = 0.0
        while d < dist:
            ix = int(math.floor(starts[s, 0] + d * dx / dist))
            iy = int(math.floor(starts[s, 1] + d * dy / dist))
            iz = int(math.floor(starts[s, 2] + d * dz / dist))
            if 0 <= ix < nx and 0 <= iy < ny and 0 <= iz < nz:
                if subject[ix, iy, iz]:
                    break
                if occupied[ix, iy, iz]:
                    out[s] = False
                    break
            d += STEP
    return out


def sees_subject(occupied: np.ndarray, subject: np.ndarray, starts: np.ndarray, point: np.ndarray) -> np.ndarray:
    """(S,) bool: the segment from each start to ``point`` (grid units), marched in half-cell steps,
    enters a ``subject`` cell before any other occupied cell."""
    return _sees_subject(occupied, subject, np.ascontiguousarray(starts, np.float64),
                         np.ascontiguousarray(point, np.float64))


def greedy(seen: np.ndarray, mass: np.ndarray, k: int, positions: np.ndarray | None = None,
           spacing: float = 0.0) -> np.ndarray:
    """Indices of ``k`` candidates chosen by the diminishing-returns gain (module docstring); with
    ``positions``, a candidate closer than ``spacing`` to a chosen one waits until no other is left."""
    weight = mass.astype(np.float64).copy()
    chosen: list[int] = []
    free = np.ones(len(seen), bool)
    apart = np.ones(len(seen), bool)
    for _ in range(min(k, len(seen))):
        gain = seen @ weight
        pool = free & apart if (free & apart).any() else free
        best = int(np.argmax(np.where(pool, gain, -1.0)))
        chosen.append(best)
        free[best] = False
        weight = np.where(seen[best], weight * 0.5, weight)
        if positions is not None and spacing > 0:
            apart &= np.linalg.norm(positions - positions[best], axis=1) >= spacing
    return np.array(chosen, np.int64)
