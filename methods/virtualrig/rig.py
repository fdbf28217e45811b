"""Virtual cameras from a :class:`~methods.virtualrig.shape.Shape`: nothing here knows any real or
test camera, only the splats' centre, bounding sphere and free space.

**Outside-in** (``object``): ``shells`` spheres around ``center`` at distances ``m·d_fit``, the
multipliers ``m`` spaced geometrically from ``radius_max`` down to ``radius_min``, where
``d_fit = radius / sin(fov/2)`` puts the whole bounding sphere inside the view cone (m = 1: the
object fills the frame; m < 1: closer views of its middle, where most detail is seen close up).
Each shell holds an equal share of ``views`` directions from a Fibonacci sphere turned by its own
seeded random rotation (no two shells share directions, and no axis of the scene's frame is
favoured); every camera looks at ``center``. When the content stands on a support plane
(:mod:`.support`: the ground under an object), no camera goes below it: each shell's directions are
then a Fibonacci spiral over the cap of directions u with up·u ≥ z_min, z_min putting the camera
one occupancy cell above the plane (z_min = (plane + cell − up·center) / distance, clamped to
[−1, 1)), turned about up by a seeded angle, and up is drawn up in the images; without a support,
the full sphere of directions.

**Inside-out** (``room``): the cameras stand inside the room, in its free space.
``positions="coverage"``: at free-space cells (:func:`coverage_candidates`) that see the
subject (the line of sight to the opacity peak reaches the subject's blob before any other occupied
cell: not from under the table top it stands on), chosen by :mod:`.coverage` — the positions whose
views of the subject see the most content, greedily with diminishing returns, :data:`SPACING` cells
apart — looking at the subject with ``fov_deg``. ``"around"`` (default): along each of
``views`` Fibonacci directions (seeded rotation) from the subject (the opacity peak of
:mod:`.shape`), at :data:`REACH_SHARE` of the free run of that ray (how far it gets before an
occupied cell that is not the subject's own; at least :data:`MIN_CELLS` cells out), looking back at
the subject with ``fov_deg``: a capture circles its subject from wherever the room leaves space.
``"enclosed"`` (the first, pre-registered version): ``⌈views / 6⌉`` positions by farthest-point
sampling over the central probes whose own enclosure reaches the room threshold (the first the one
with the most clearance), each the centre of a cube of six 90° views turned by a seeded random
rotation. On bonsai-7k those positions all lie below the table top, hidden from the bonsai, and its
selection run pruned worse than random (``results/virtualrig/selection.md``): the open space a
capture is taken from is the *less* enclosed part of a room.

Images are square, ``resolution`` px; focal length from the field of view. ``harness diagnose SCENE
--method virtual-rig`` draws where the cameras went.
"""

from __future__ import annotations

import math

import numpy as np

from harness.core.cameras import Camera
from harness.core.sphere import fibonacci_sphere, random_rotation
from methods.virtualrig import coverage
from methods.virtualrig.shape import MIN_CLEARANCE, SUBJECT_CELLS, Shape, free_reach
from methods.virtualrig.support import Support

CUBE_FOV = 90.0
REACH_SHARE = 0.7
MIN_CELLS = 2.0
MAX_CANDIDATES = 600  # room positions the coverage rig weighs
SPACING = 2.0  # cells between two chosen room positions (while others remain)


def _camera(eye, forward, *, fov_deg: float, resolution: int, name: str, up=None) -> Camera:
    """A square camera at ``eye`` looking along ``forward``; roll: ``up`` drawn upwards when given and
    not along ``forward``, else the world axis least along it."""
    forward = np.asarray(forward, np.float64)
    if up is None or abs(np.dot(up, forward)) > 0.999 * np.linalg.norm(forward):
        up = np.eye(3)[int(np.argmin(np.abs(forward)))]
    return Camera.look_at(eye, eye + forward, up, fov_y_deg=fov_deg, width=resolution, height=resolution, name=name)


def shell_multipliers(shells: int, radius_min: float, radius_max: float) -> np.ndarray:
    """Distance multipliers of the shells, geometric from ``radius_max`` to ``radius_min``."""
    return np.geomspace(radius_max, radius_min, shells) if shells > 1 else np.array([radius_max])


def cap_directions(n: int, up: np.ndarray, z_min: float, angle: float) -> np.ndarray:
    """``n`` unit vectors spread evenly (a Fibonacci spiral) over the directions u with up·u ≥ z_min,
    turned by ``angle`` about ``up``."""
    i = np.arange(n) + 0.5
    z = 1.0 - (1.0 - z_min) * i / n
    phi = angle + i * math.pi * (3.0 - math.sqrt(5.0))
    rho = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    helper = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(up, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    return (rho * np.cos(phi))[:, None] * e1 + (rho * np.sin(phi))[:, None] * e2 + z[:, None] * up


def outside_in(shape: Shape, *, views: int, shells: int, radius_min: float, radius_max: float,
               fov_deg: float, resolution: int, seed: int, support: Support | None = None) -> list[Camera]:
    """The object rig (module docstring)."""
    rng = np.random.default_rng(seed)
    d_fit = shape.radius / math.sin(math.radians(fov_deg) / 2.0)
    counts = np.full(shells, views // shells) + (np.arange(shells) < views % shells)
    up = None if support is None or support.up is None else support.up
    cams = []
    for s, (m, n) in enumerate(zip(shell_multipliers(shells, radius_min, radius_max), counts)):
        if up is None:
            dirs = fibonacci_sphere(int(n)) @ random_rotation(rng).T
        else:
            z_min = (support.height + shape.cell - float(up @ shape.center)) / (m * d_fit)
            dirs = cap_directions(int(n), up, float(np.clip(z_min, -1.0, 0.999)), rng.uniform(0, 2 * math.pi))
        for i, u in enumerate(dirs):
            cams.append(_camera(shape.center + m * d_fit * u, -u, fov_deg=fov_deg, resolution=resolution,
                                name=f"vr_shell{s}_{i:03d}", up=up))
    return cams


def farthest_points(points: np.ndarray, k: int) -> np.ndarray:
    """Indices of ``k`` points by farthest-point sampling from point 0."""
    k = min(k, len(points))
    chosen = [0]
    d = np.linalg.norm(points - points[0], axis=1)
    while len(chosen) < k:
        nxt = int(np.argmax(d))
        chosen.append(nxt)
        d = np.minimum(d, np.linalg.norm(points - points[nxt], axis=1))
    return np.array(chosen, np.int64)


def around_subject(shape: Shape, *, views: int, fov_deg: float, resolution: int, seed: int) -> list[Camera]:
    """The room rig with ``positions="around"`` (module docstring)."""
    rng = np.random.default_rng(seed)
    dirs = fibonacci_sphere(views) @ random_rotation(rng).T
    reach = free_reach(shape.occupied, (shape.peak - shape.origin) / shape.cell, dirs, SUBJECT_CELLS)
    dist = np.maximum(REACH_SHARE * reach, MIN_CELLS) * shape.cell
    return [_camera(shape.peak + d * u, -u, fov_deg=fov_deg, resolution=resolution, name=f"vr_around_{i:03d}")
            for i, (u, d) in enumerate(zip(dirs, dist))]


def coverage_candidates(shape: Shape, seed: int) -> np.ndarray:
    """World positions a room camera may stand at: free cells with :data:`.shape.MIN_CLEARANCE`
    clearance within the content's weighted median distance of its centre, at least
    :data:`MIN_CELLS` cells from the subject, at most :data:`MAX_CANDIDATES` (seeded sample)."""
    free = np.argwhere(~shape.occupied & (shape.clearance >= MIN_CLEARANCE))
    world = shape.origin + (free + 0.5) * shape.cell
    near = np.linalg.norm(world - shape.center, axis=1) <= shape.median_distance
    near &= np.linalg.norm(world - shape.peak, axis=1) >= MIN_CELLS * shape.cell
    world = world[near]
    if len(world) > MAX_CANDIDATES:
        world = world[np.sort(np.random.default_rng(seed).choice(len(world), MAX_CANDIDATES, replace=False))]
    return world


def by_coverage(shape: Shape, *, views: int, fov_deg: float, resolution: int, seed: int) -> list[Camera]:
    """The room rig with ``positions="coverage"`` (module docstring)."""
    where = coverage_candidates(shape, seed)
    starts = (where - shape.origin) / shape.cell
    subject = (shape.peak - shape.origin) / shape.cell
    where = where[coverage.sees_subject(shape.occupied, shape.subject, starts, subject)]
    if len(where) == 0:
        raise ValueError("inside-out virtual rig: no free-space position in sight of the subject")
    forwards = (shape.peak - where) / np.linalg.norm(shape.peak - where, axis=1, keepdims=True)
    seen = coverage.visibility(shape.occupied, (where - shape.origin) / shape.cell, forwards, fov_deg)
    pick = coverage.greedy(seen, shape.mass[shape.occupied], views, positions=where / shape.cell,
                           spacing=SPACING)
    return [_camera(where[k], forwards[k], fov_deg=fov_deg, resolution=resolution, name=f"vr_cover_{i:03d}")
            for i, k in enumerate(pick)]


def inside_out(shape: Shape, *, views: int, resolution: int, seed: int, positions: str = "around",
               room_enclosure: float = 0.8, fov_deg: float = 60.0) -> list[Camera]:
    """The room rig (module docstring)."""
    if positions == "coverage":
        return by_coverage(shape, views=views, fov_deg=fov_deg, resolution=resolution, seed=seed)
    if positions == "around":
        return around_subject(shape, views=views, fov_deg=fov_deg, resolution=resolution, seed=seed)
    if positions != "enclosed":
        raise ValueError(f"unknown inside-out positions {positions!r}; known: coverage, around, enclosed")
    where = shape.probes[shape.probe_enclosure >= room_enclosure]
    if len(where) == 0:
        raise ValueError("inside-out virtual rig: the scene has no enclosed free space to stand in")
    rng = np.random.default_rng(seed)
    cams = []
    for p, idx in enumerate(farthest_points(where, -(-views // 6))):
        rot = random_rotation(rng)
        for f, forward in enumerate(np.concatenate([rot.T, -rot.T])):
            cams.append(_camera(where[idx], forward, fov_deg=CUBE_FOV, resolution=resolution,
                                name=f"vr_pos{p}_{f}"))
    return cams
