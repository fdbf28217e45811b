"""Which way is up: the plane a scene's content stands on, found from the splats alone.

A capture is taken from above the ground its subject stands on, so a camera below that plane sees
its underside and nothing of the subject. The support is looked for as a *dominant plane under the
content* among the directions the opacity-weighted normals favour:

1. **Normals**: a splat is *flat* when its shortest axis is at most :data:`FLAT` of the geometric
   mean of the other two; its normal is that axis, its weight opacity × the area s₁s₂ of its disc.
   Flat splats with opacity ≥ :data:`OPAQUE` inside the content's bounding sphere vote (a seeded
   weighted sample of at most :data:`SAMPLE` of them for the peaks; the tests below read seeded
   samples of at most :data:`TEST_SAMPLE` opaque and flat splats).
2. **Candidate axes**: the peaks of the axial normal density over :data:`N_DIRS` directions of a
   hemisphere, kernel max(0, |n·a| − cos 15°), at most :data:`PEAKS` peaks at least 30° apart, each
   with at least :data:`MIN_PEAK` of the highest peak's density. Each axis is tried both ways (u and
   −u), turned to the geometric normal of its slab's plane (:func:`fit_plane`).
3. **Support slab** along u: heights h = p·u of the opaque splats; the slab one occupancy cell thick
   (two bin grids half a cell apart) holding the most weight of flat splats whose normal is within
   15° of u.
4. **Tests**: ``one_sided``, the share of the opaque mass outside the slab that lies above it
   (h larger); ``coverage``, the share of the content's footprint above the slab (cells of a 2D
   grid in the plane, one occupancy cell wide, holding content above the slab) that the slab's flat
   splats cover (dilated by one cell). The top of an object is one-sided too, but it covers only a
   small part of the object's footprint; a ground or a floor covers it.
5. ``up`` is the u with the highest one_sided × coverage among those with one_sided ≥
   :data:`MIN_ONE_SIDED` and coverage ≥ :data:`MIN_COVERAGE`; without one, the scene has no support
   (a floating object, a sheet) and ``up`` is None.

In a room the walls, the floor and the ceiling are all one-sided planes covering the room, so the
room rig does not use this test (:mod:`.coverage` keeps its cameras in sight of the subject instead).

Every number is this project's choice, fixed before any evaluation; :meth:`Support.describe` prints
what was found so a wrong call can be seen (and ``up`` overrides it in the pruner's parameters).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import binary_dilation

from harness.core.scene import GaussianScene, opacities, quat_to_rotmat
from harness.core.sphere import fibonacci_sphere

FLAT = 0.3
OPAQUE = 0.5
SAMPLE = 20_000
TEST_SAMPLE = 100_000  # opaque splats (and flat ones) the slab tests read (seeded uniform sample)
N_DIRS = 1000
PEAKS = 8
MIN_PEAK = 0.05  # a peak's density, relative to the highest one
BAND = 2  # occupancy cells on either side of the slab left out of the one-sided test (a surface's thickness)
ALIGN_COS = math.cos(math.radians(15.0))
PEAK_SEPARATION_COS = math.cos(math.radians(30.0))
MIN_ONE_SIDED = 0.8
MIN_COVERAGE = 0.6


@dataclass(frozen=True)
class Support:
    """The support plane of a scene, or none (``up`` None)."""

    up: np.ndarray | None  # (3,) unit, pointing from the plane to the content
    height: float  # the plane's top: p·up of its upper face (nan without support)
    one_sided: float
    coverage: float

    def describe(self) -> str:
        if self.up is None:
            return (f"no support plane (best: one-sided {self.one_sided:.2f}, covers {self.coverage:.2f} "
                    "of the footprint): views from every direction")
        return (f"support plane ⟂ up {np.round(self.up, 3).tolist()} at height {self.height:.3g} "
                f"(one-sided {self.one_sided:.2f}, covers {self.coverage:.2f} of the footprint)")

    def above(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Which ``points`` (K, 3) lie above the plane by at least ``margin`` (all without support)."""
        if self.up is None:
            return np.ones(len(points), bool)
        return points @ self.up >= self.height + margin


def _frame(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(u, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(u, e1)


def flat_normals(scene: GaussianScene, core: np.ndarray, seed: int = 0):
    """(normals (F, 3), weights (F,), centres (F, 3)) of the opaque flat splats in ``core`` (mask), at
    most :data:`TEST_SAMPLE` of them (seeded)."""
    scales = np.exp(scene.scales_log.astype(np.float64))
    order = np.argsort(scales, axis=1)
    s = np.take_along_axis(scales, order, axis=1)
    flat = (s[:, 0] <= FLAT * np.sqrt(s[:, 1] * s[:, 2])) & (opacities(scene) >= OPAQUE) & core
    idx = _at_most(np.flatnonzero(flat), TEST_SAMPLE, np.random.default_rng(seed))
    rot = quat_to_rotmat(scene.quats[idx].astype(np.float64))
    normals = rot[np.arange(len(idx)), :, order[idx, 0]]
    weights = opacities(scene)[idx].astype(np.float64) * s[idx, 1] * s[idx, 2]
    return normals, weights, scene.means[idx].astype(np.float64)


def _at_most(idx: np.ndarray, k: int, rng) -> np.ndarray:
    return idx if len(idx) <= k else np.sort(rng.choice(idx, k, replace=False))


def normal_peaks(normals: np.ndarray, weights: np.ndarray, seed: int) -> list[np.ndarray]:
    """Axes where the axial normal density peaks (module docstring, step 2)."""
    if len(normals) == 0 or weights.sum() <= 0:
        return []
    if len(normals) > SAMPLE:
        pick = np.random.default_rng(seed).choice(len(normals), SAMPLE, replace=False, p=weights / weights.sum())
        normals, weights = normals[pick], np.ones(SAMPLE)
    dirs = fibonacci_sphere(2 * N_DIRS)
    dirs = dirs[dirs[:, 2] >= 0]
    density = weights @ np.maximum(np.abs(normals @ dirs.T) - ALIGN_COS, 0.0)
    peaks: list[np.ndarray] = []
    highest = float(density.max())
    for _ in range(PEAKS):
        k = int(np.argmax(density))
        if density[k] <= 0 or density[k] < MIN_PEAK * highest:
            break
        peaks.append(dirs[k])
        density = np.where(np.abs(dirs @ dirs[k]) >= PEAK_SEPARATION_COS, 0.0, density)
    return peaks


def fit_plane(u: np.ndarray, normals: np.ndarray, flat_w: np.ndarray, flat_pts: np.ndarray, cell: float,
              rounds: int = 2) -> np.ndarray:
    """``u`` turned to the normal of the plane through its support slab: the weighted least-spread
    axis of the centres of the aligned flat splats within :data:`BAND` cells of the slab, ``rounds``
    times (a splat's own normal is a noisy estimate of its surface's, and a one-cell slab needs the
    plane's)."""
    for _ in range(rounds):
        aligned = np.abs(normals @ u) >= ALIGN_COS
        if aligned.sum() < 3:
            break
        h = flat_pts[aligned] @ u
        mid = _slab(h, flat_w[aligned], cell) + 0.5 * cell
        near = np.abs(h - mid) <= BAND * cell
        if near.sum() < 3:
            break
        pts, w = flat_pts[aligned][near], flat_w[aligned][near]
        c = pts - np.average(pts, axis=0, weights=w)
        n = np.linalg.eigh((c * w[:, None]).T @ c)[1][:, 0]
        u = n if n @ u >= 0 else -n
    return u / np.linalg.norm(u)


def _slab(h_flat: np.ndarray, w_flat: np.ndarray, cell: float) -> float:
    """Bottom of the one-cell slab holding the most weight (two bin grids half a cell apart)."""
    best, bottom = -1.0, float(h_flat.min())
    for shift in (0.0, 0.5 * cell):
        lo = h_flat.min() - shift
        hist = np.bincount(((h_flat - lo) // cell).astype(np.int64), weights=w_flat)
        k = int(np.argmax(hist))
        if hist[k] > best:
            best, bottom = hist[k], lo + k * cell
    return bottom


def _cells(points2d: np.ndarray, lo: np.ndarray, cell: float, dims: tuple[int, int]) -> np.ndarray:
    """The cells of a 2D grid (corner ``lo``, edge ``cell``) that hold a point."""
    idx = np.clip(((points2d - lo) // cell).astype(np.int64), 0, np.array(dims) - 1)
    grid = np.zeros(dims, bool)
    grid[idx[:, 0], idx[:, 1]] = True
    return grid


def test_axis(u, points, mass, normals, flat_w, flat_pts, cell) -> tuple[float, float, float]:
    """(slab top, one_sided, coverage) of candidate up ``u`` (module docstring, steps 3–4)."""
    aligned = normals @ u >= ALIGN_COS
    aligned |= -(normals @ u) >= ALIGN_COS
    if not aligned.any():
        return math.nan, 0.0, 0.0
    bottom = _slab(flat_pts[aligned] @ u, flat_w[aligned], cell)
    top = bottom + cell
    h = points @ u
    above, below = h >= top + BAND * cell, h < bottom - BAND * cell
    rest = mass[above].sum() + mass[below].sum()
    one_sided = float(mass[above].sum() / rest) if rest > 0 else 0.0
    e1, e2 = _frame(u)
    plane = (flat_pts @ u >= bottom) & (flat_pts @ u < top) & aligned
    above_2d = np.stack([points[above] @ e1, points[above] @ e2], 1)
    if not len(above_2d) or not plane.any():
        return top, one_sided, 0.0
    plane_2d = np.stack([flat_pts[plane] @ e1, flat_pts[plane] @ e2], 1)
    both = np.concatenate([above_2d, plane_2d])
    lo = both.min(0)
    dims = tuple(int(d) for d in np.maximum(np.ceil((both.max(0) - lo) / cell), 1).astype(np.int64) + 1)
    covered = binary_dilation(_cells(plane_2d, lo, cell, dims), np.ones((3, 3), bool))
    idx = np.clip(((above_2d - lo) // cell).astype(np.int64), 0, np.array(dims) - 1)
    on = covered[idx[:, 0], idx[:, 1]]
    return top, one_sided, float(mass[above][on].sum() / mass[above].sum())


def find_support(scene: GaussianScene, center: np.ndarray, radius: float, cell: float, seed: int = 0) -> Support:
    """The :class:`Support` of the content within ``radius`` of ``center`` (module docstring)."""
    means = scene.means.astype(np.float64)
    finite = np.all(np.isfinite(means), axis=1)
    core = finite & (np.linalg.norm(np.where(finite[:, None], means, 0.0) - center, axis=1) <= radius)
    opaque = core & (opacities(scene) >= OPAQUE)
    rng = np.random.default_rng(seed)
    opaque = _at_most(np.flatnonzero(opaque), TEST_SAMPLE, rng)
    points, mass = means[opaque], opacities(scene)[opaque].astype(np.float64)
    normals, flat_w, flat_pts = flat_normals(scene, core, seed)
    best = (0.0, None, math.nan, 0.0, 0.0)
    for axis in normal_peaks(normals, flat_w, seed):
        for u in (axis, -axis):
            u = fit_plane(u, normals, flat_w, flat_pts, cell)
            top, one_sided, coverage = test_axis(u, points, mass, normals, flat_w, flat_pts, cell)
            if one_sided * coverage > best[0] or best[1] is None and one_sided * coverage >= best[0]:
                best = (one_sided * coverage, u, top, one_sided, coverage)
    _, u, top, one_sided, coverage = best
    if u is None or one_sided < MIN_ONE_SIDED or coverage < MIN_COVERAGE:
        return Support(None, math.nan, one_sided, coverage)
    return Support(u, top, one_sided, coverage)

