"""Scene-shape analysis from the splats alone: is the content an object seen from outside, or a
room (an unbounded capture) seen from inside, and where is there free space to put a camera?

Everything is opacity-weighted (weights o = sigmoid(logit); all ones when every o is 0), uses every
splat (no sampling: deterministic in the scene) and ignores non-finite centres.

* ``center``: the per-axis weighted median of the centres.
* ``radius``: the weighted 95th percentile of the distance to ``center`` — the bounding sphere of
  the content with far floaters left out; ``extent`` the weighted 90th percentile.
* **Occupancy grid**: cubic cells, ``grid`` of them along the longest side of the box of the splats
  inside the bounding sphere. A cell is *occupied* when the opacity of the splats whose centres lie
  in it sums to at least ``occupied_mass`` (default 1: about one opaque splat), so thin surfaces
  block rays and a few faint floaters do not; then a morphological closing (3×3×3) seals the
  one-cell holes that sparse walls leave, so rays do not leak through them.
* **Free-space probes**: unoccupied cells whose clearance (Euclidean distance to the nearest
  occupied cell, in cells) is at least :data:`MIN_CLEARANCE` and whose centre lies in the *central
  region*, within the weighted 25th percentile of the distance to ``center`` (where a viewer of a
  room capture stands; three quarters of the content lies farther out); at most :data:`MAX_PROBES`
  of them (seeded subsample).
* **Enclosure of a probe**: the share of :data:`N_RAYS` Fibonacci directions whose ray, marched
  through the grid in half-cell steps, meets an occupied cell before leaving the grid. From inside a
  room most rays meet a wall, floor or ceiling; next to an object, only those pointing at it or at
  the ground it stands on.
* **Kind**: ``room`` when the median enclosure of the probes is at least ``room_enclosure``
  (default 0.8: content in four fifths of all directions), else ``object`` (also when there is
  no probe: the centre is inside solid content). The probes are the inside-out rig's candidate
  camera positions (:mod:`.rig`), kept for any kind (most clearance first) with their enclosure, so
  ``rig: inside-out`` can be forced where such free space exists.
* **Subject**: ``peak``, the cell with the most opacity mass after Gaussian smoothing (σ = 1 cell)
  — what a room capture circles (bonsai-7k: the bonsai on its table); ``subject``, its blob: the
  connected cells (faces) around the peak whose smoothed mass is at least :data:`SUBJECT_SHARE` of
  the peak's (a table top it stands on is a thin, lighter layer, not part of it). :func:`free_reach` measures
  how far a ray from it runs through free space, which is where the room rig puts its cameras.

Measured on the five default scenes (render-free, before any evaluation; grid 32, mass 1), and the
threshold set between them: median enclosure of the central probes bonsai-7k 0.92 (a Mip-NeRF 360
room), bonsai-7k-mini 0.70 (its table-top crop: table, pot, some floor), playbot 0.56 (robot on a
ground patch), luigi 0.33, grape-small 0.08.
The numbers (occupied mass, clearance, ray count, the 0.8 enclosure) are this project's choices,
fixed before any evaluation; the statistic is printed by ``describe()`` for any scene so a wrong
call can be seen, and ``rig: outside-in | inside-out`` overrides it. The subject and free reach were
added after the first selection run (``results/virtualrig/selection.md``, v2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import binary_closing, distance_transform_edt, gaussian_filter, label

from harness.core.scene import GaussianScene, opacities
from harness.core.sphere import fibonacci_sphere

MIN_CLEARANCE = 1.5  # cells between a probe and the nearest occupied cell
MAX_PROBES = 512
N_RAYS = 64
CENTRAL_QUANTILE = 0.25  # the central region: within this weighted quantile of the distance to the centre
SUBJECT_SHARE = 0.5  # smoothed mass, relative to the peak's, of the subject's blob
SUBJECT_CELLS = 1.5  # occupied cells this close to the subject's peak are the subject, not an obstacle


@dataclass(frozen=True)
class Shape:
    """What the virtual rig knows about a scene (see the module docstring)."""

    kind: str  # "object" | "room"
    center: np.ndarray  # (3,)
    extent: float  # weighted P90 distance to center
    radius: float  # weighted P95 distance to center (bounding sphere)
    cell: float  # occupancy grid cell edge (world units)
    enclosure: float  # median enclosure of the central free-space probes (0 without probes)
    probes: np.ndarray  # (K, 3) central free-space positions (world), most clearance first
    probe_clearance: np.ndarray  # (K,) their clearance (world units)
    probe_enclosure: np.ndarray  # (K,) their enclosure
    peak: np.ndarray  # (3,) the subject: peak of the smoothed opacity mass
    occupied: np.ndarray  # (X, Y, Z) bool occupancy grid
    mass: np.ndarray  # (X, Y, Z) opacity mass per cell
    subject: np.ndarray  # (X, Y, Z) bool: the subject's blob around the peak
    clearance: np.ndarray  # (X, Y, Z) distance (cells) to the nearest occupied cell
    median_distance: float  # weighted median distance of the content to center
    origin: np.ndarray  # (3,) world position of the grid's corner

    def describe(self) -> str:
        return (f"{self.kind}: centre {np.round(self.center, 3).tolist()}, radius {self.radius:.3g}, "
                f"cell {self.cell:.3g}, median enclosure of central free space {self.enclosure:.2f}, "
                f"{len(self.probes)} free-space probes")


def weighted_quantile(values: np.ndarray, weights: np.ndarray, q):
    """The smallest value whose cumulative weight reaches ``q`` of the total (a weighted quantile);
    ``q`` a number or a sequence (one sort for all). Ties may sort in any order: the value is the same."""
    order = np.argsort(values)
    cum = np.cumsum(weights[order])
    k = np.minimum(np.searchsorted(cum, np.asarray(q, np.float64) * cum[-1]), len(cum) - 1)
    out = values[order][k]
    return float(out) if np.ndim(out) == 0 else out.astype(np.float64)


def _weights(scene: GaussianScene) -> tuple[np.ndarray, np.ndarray]:
    means = scene.means.astype(np.float64)
    finite = np.all(np.isfinite(means), axis=1)
    if not finite.any():
        raise ValueError("the scene has no finite splat centre to place virtual cameras around")
    w = opacities(scene).astype(np.float64)[finite]
    return means[finite], (w if w.sum() > 0 else np.ones_like(w))


def occupancy(points: np.ndarray, weights: np.ndarray, grid: int, occupied_mass: float):
    """(occupied (X, Y, Z) bool, opacity mass per cell, origin (3,), cell edge) of the cubic grid over
    ``points``' box."""
    lo, hi = points.min(0), points.max(0)
    cell = max(float((hi - lo).max()) / grid, 1e-9)
    dims = np.maximum(np.ceil((hi - lo) / cell).astype(np.int64), 1)
    idx = np.minimum(((points - lo) / cell).astype(np.int64), dims - 1)
    flat = np.ravel_multi_index(idx.T, tuple(dims))
    mass = np.bincount(flat, weights=weights, minlength=int(np.prod(dims))).reshape(tuple(dims))
    occupied = binary_closing(np.pad(mass >= occupied_mass, 1), np.ones((3, 3, 3), bool))[1:-1, 1:-1, 1:-1]
    return occupied, mass, lo, cell


def march(occupied: np.ndarray, starts: np.ndarray, dirs: np.ndarray, spare: float = 0.0):
    """Rays from each start (grid coordinates, cell units) along each direction, in half-cell steps:
    (blocked (S, D) bool, reach (S, D) cells). A ray stops at the first occupied cell farther than
    ``spare`` cells from its start (blocked) or where it leaves the grid; reach is its last free step."""
    dims = np.array(occupied.shape)
    blocked = np.zeros((len(starts), len(dirs)), bool)
    reach = np.zeros(blocked.shape)
    alive = np.ones_like(blocked)
    for t in np.arange(0.5, float(np.linalg.norm(dims)) + 1.0, 0.5):
        pos = np.floor(starts[:, None, :] + t * dirs[None, :, :]).astype(np.int64)
        alive &= np.all((pos >= 0) & (pos < dims), axis=2)
        if not alive.any():
            break
        hit = np.zeros_like(blocked)
        check = alive & (t > spare)
        hit[check] = occupied[tuple(pos[check].T)]
        blocked |= hit
        alive &= ~hit
        reach[alive] = t
    return blocked, reach


def ray_enclosure(occupied: np.ndarray, starts: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Share of ``dirs`` whose ray from each start meets an occupied cell before leaving the grid."""
    return march(occupied, starts, dirs)[0].mean(axis=1)


def free_reach(occupied: np.ndarray, start: np.ndarray, dirs: np.ndarray, spare: float) -> np.ndarray:
    """Per direction, how far (cells) a ray from ``start`` runs through free space, occupied cells
    within ``spare`` cells of the start (the subject itself) not counting."""
    return march(occupied, start[None, :], dirs, spare)[1][0]


def _subsample(cells: np.ndarray, seed: int) -> np.ndarray:
    if len(cells) <= MAX_PROBES:
        return cells
    return cells[np.sort(np.random.default_rng(seed).choice(len(cells), MAX_PROBES, replace=False))]


def analyse(scene: GaussianScene, *, grid: int = 32, occupied_mass: float = 1.0, room_enclosure: float = 0.8,
            seed: int = 0) -> Shape:
    """The :class:`Shape` of ``scene`` (module docstring)."""
    if len(scene) == 0:
        raise ValueError("cannot place virtual cameras around an empty scene")
    pts, w = _weights(scene)
    center = np.array([weighted_quantile(pts[:, k], w, 0.5) for k in range(3)])
    dist = np.linalg.norm(pts - center, axis=1)
    radius, extent, central, half = weighted_quantile(dist, w, [0.95, 0.90, CENTRAL_QUANTILE, 0.5])
    radius, extent = max(float(radius), 1e-6), max(float(extent), 1e-6)
    core = dist <= radius
    occupied, mass, origin, cell = occupancy(pts[core], w[core], grid, occupied_mass)
    clearance = distance_transform_edt(~occupied) if occupied.any() else np.full(occupied.shape, np.inf)
    free = np.argwhere((~occupied) & (clearance >= MIN_CLEARANCE))
    world = origin + (free + 0.5) * cell
    cells = _subsample(free[np.linalg.norm(world - center, axis=1) <= central], seed)
    enc = ray_enclosure(occupied, cells + 0.5, fibonacci_sphere(N_RAYS)) if len(cells) else np.zeros(0)
    median = float(np.median(enc)) if len(enc) else 0.0
    smooth = gaussian_filter(mass, 1.0, mode="constant")
    peak_cell = np.array(np.unravel_index(np.argmax(smooth), mass.shape))
    blobs = label(smooth >= SUBJECT_SHARE * smooth[tuple(peak_cell)])[0]
    subject = blobs == blobs[tuple(peak_cell)]
    order = np.argsort(-clearance[tuple(cells.T)], kind="stable")
    cells = cells[order]
    return Shape("room" if median >= room_enclosure else "object", center, extent, radius, cell, median,
                 origin + (cells + 0.5) * cell, clearance[tuple(cells.T)] * cell, enc[order],
                 origin + (peak_cell + 0.5) * cell, occupied, mass, subject, clearance,
                 float(half), origin)
