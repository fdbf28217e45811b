"""Synthetic camera rigs for scenes without cameras: ``orbit``, ``room``, ``forward`` (and ``auto``).

Every rig lays ``n = n_train + n_test`` views out along one path, deterministic in ``seed`` (the
seed only sets the start azimuth and small per-view jitter), and holds out ``n_test`` of them spread
evenly along the path (view ``⌊(j + ½)·n / n_test⌋`` for j < n_test, the analogue of 3DGS's
every-8th ``llffhold``), so ``train`` and ``test`` are disjoint and test views interleave with
training views. Images are ``longest_side`` px on their long side (1024, the CTC setting) with
``aspect = width / height``; the principal point is the image centre; ``fov_deg`` is the field of view
across the long side. Placement uses :mod:`harness.views.placement` (opacity-weighted, floaters removed).

**Distance fit** (every rig): a camera looking from direction ``u`` at ``target`` has the rotation
of :meth:`Camera.look_at`, which does not depend on the distance ``d``. A point with camera-frame
offset (x, y, z_r) from ``target`` lies at depth z_r + d and inside the central ``fill`` part of the
image iff f·|x| ≤ fill·(w/2)·(z_r + d) (same for y, h), i.e. d ≥ f·|x| / (fill·w/2) − z_r. ``d`` is
the 99th percentile over the content points of the largest such bound (and of 0.3 − z_r, keeping
them in front of the near plane), so the content fills most of the frame in every view. Views whose
fit is closer than the median fit of the rig use the median distance instead, as a real capture
keeps its distance: a view where the content looks compact is not turned into a close-up.

* ``orbit`` (object-centric): target = robust centre; elevation rings (default 5°, 25°, 45°) visited
  in turn while the azimuth sweeps 360° once; fill 0.85 of the frame (margin for the splats' own extent).
* ``room`` (Mip-NeRF 360 style, e.g. bonsai): the capture circles the room's central object from
  inside the room, looking inward and down at it. Target = the density peak; the distance is fitted
  so the points within the 25 % nearest to the peak fill 0.6 of the frame (the room shows around
  it), capped at half the median distance of the content from the peak so cameras stay inside the
  walls; default elevations 15°, 30°.
* ``forward`` (LLFF style): an arc of ±20° (and a ±5° wobble across it) around one front direction
  ``F`` (from the content towards the cameras). ``F`` is given, else the principal axis of least
  spread of the content (looking along it shows the broadest face: the normal of a sheet-like crop),
  signed to point up (dot(F, up) ≥ 0), or along +x of the horizontal basis when perpendicular to up.
  View i looks along normalise(F + tan(aᵢ)·S + tan(bᵢ)·V), S = up × F, V = F × S; fill 0.85.
* ``auto`` (a heuristic, measured on the five named scenes): ``room`` when the content both surrounds
  a point inside it (:func:`harness.views.placement.enclosure` ≥ 0.5: bonsai-7k 0.62, the object scenes
  ≤ 0.42) and spreads far beyond the dense core (90th / 10th percentile of the distance to the
  density peak ≥ 10: bonsai-7k 14.9, the object scenes 4.6–8.0; a solid cloud, which an eye inside
  also sees all around, stays near 3); else ``orbit``. Never ``forward``: a forward-facing capture
  cannot be told from splats.

:data:`SCENE_RIGS` holds the named datasets' own rigs (``rig: default``; looked at on contact sheets).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from harness.core.cameras import Camera
from harness.core.scene import GaussianScene
from harness.views.placement import Placement, enclosure, placement

RIG_NAMES = ("orbit", "room", "forward", "auto")
#: what a config's ``rig:`` and ``harness render --rig`` accept: a rig, or ``default`` (the scene's own)
RIG_CHOICES = ("default",) + RIG_NAMES
#: view defaults of the whole house (configs, ``harness render``, benchmarks)
LONGEST_SIDE = 1024  # px, the CTC setting
ASPECT = 4.0 / 3.0
N_TRAIN = 48
N_TEST = 8
#: the most views of one kind (training or held-out) a rig is built with, in configs and `harness
#: render` alike: more is hours of rendering per scene, and almost surely a typo (--n-test 10000)
MAX_VIEWS = 1000
FOV_DEG = 60.0  # across the long side
NEAR_MARGIN = 0.3  # keep content beyond the renderer's z > 0.2 cull
DISTANCE_QUANTILE = 99.0
ENCLOSURE_ROOM = 0.5
ROOM_SPREAD = 10.0
OBJECT_FILL = 0.85


@dataclass(frozen=True)
class RigViews:
    train: list[Camera]
    test: list[Camera]
    rig: str = ""

    @property
    def all(self) -> list[Camera]:
        """Every view in path order (train and test interleaved back together)."""
        return sorted(self.train + self.test, key=lambda c: c.name)


@dataclass(frozen=True)
class RigDefaults:
    """Per-scene rig settings; ``None`` fields fall back to the rig's own defaults."""

    rig: str
    up: tuple[float, float, float] | None = None
    aspect: float | None = None
    elevations: tuple[float, ...] | None = None
    note: str = ""


#: Defaults per named dataset (:mod:`harness.io.datasets`), chosen by looking at contact sheets.
SCENE_RIGS: dict[str, RigDefaults] = {
    "grape-small": RigDefaults(
        "forward", up=(0.0, 1.0, 0.0),
        note="a thin curved sheet cropped from a larger scene: face it (edge-on orbit views are empty)"),
    "luigi": RigDefaults(
        "orbit", up=(0.0, 1.0, 0.0), aspect=1.0, elevations=(-10.0, 10.0, 30.0),
        note="a standing figure (y up): orbit, square frames, from slightly below to above"),
    "bonsai-7k-mini": RigDefaults(
        "orbit", up=(0.0, -1.0, 0.0), elevations=(15.0, 30.0, 45.0),
        note="object-centric crop (table, pot, tree): orbit from above the table top"),
    "bonsai-7k": RigDefaults(
        "room", up=(0.0, -1.0, 0.0), elevations=(25.0, 40.0),
        note="Mip-NeRF 360 room: cameras inside, circling and looking down at the bonsai"),
    "playbot": RigDefaults(
        "orbit", up=(0.0, -1.0, 0.0), elevations=(20.0, 35.0, 50.0),
        note="robot above a 2 × 2 ground patch at y = 0: orbit from above the ground only"),
    # generated scenes (harness.io.generated): up is where the generator's +z went; the rig kinds' own
    # elevations (orbit from above the ground, a room circled from inside)
    "synth-room": RigDefaults(
        "room", up=(-0.6206, -0.6344, 0.4609), elevations=(15.0, 30.0),
        note="generated room (floor, walls, table with a vase and a plant): cameras inside, circling the table"),
    "synth-statue": RigDefaults(
        "orbit", up=(0.0608, -0.9533, -0.2959), elevations=(5.0, 25.0, 45.0),
        note="generated figure on a pedestal on a 3 × 3 ground patch: orbit from above the ground"),
}

_RIG_DEFAULT_ELEVATIONS = {"orbit": (5.0, 25.0, 45.0), "room": (15.0, 30.0), "forward": (0.0,)}


def image_size(longest_side: int, aspect: float) -> tuple[int, int]:
    """(width, height) with the long side ``longest_side`` and width/height ≈ ``aspect``."""
    if longest_side < 1 or not aspect > 0 or not math.isfinite(aspect):
        raise ValueError("longest_side must be ≥ 1 and aspect a positive number")
    if aspect >= 1:
        return int(longest_side), max(1, round(longest_side / aspect))
    return max(1, round(longest_side * aspect)), int(longest_side)


def held_out_indices(n_total: int, n_test: int) -> list[int]:
    """Indices ⌊(j + ½)·n_total / n_test⌋ for j < n_test: evenly spread, distinct if n_test ≤ n_total."""
    return [int((j + 0.5) * n_total / n_test) for j in range(n_test)]


def look_from(target, direction, d: float, *, up, width, height, fov_deg, name="") -> Camera:
    """The camera at ``target + d·direction`` looking at ``target``, ``fov_deg`` across the long side."""
    f = max(width, height) / (2.0 * math.tan(math.radians(fov_deg) / 2.0))
    fov_y = math.degrees(2.0 * math.atan(height / (2.0 * f)))
    return Camera.look_at(target + d * direction, target, up, fov_y_deg=fov_y,
                          width=width, height=height, name=name)


def fit_distance(target, direction, points, *, up, width, height, fov_deg, fill) -> float:
    """Smallest distance putting the content points inside the central ``fill`` of the frame
    (99th percentile of the per-point bounds, module docstring)."""
    target = np.asarray(target, np.float64)
    # the rotation alone matters, and it does not depend on where the camera stands: placed at the
    # origin, the probe's direction is exact at any scale (at target + 1·u a target at 1e17 swallows u)
    probe = look_from(np.zeros(3), direction, 1.0, up=up, width=width, height=height, fov_deg=fov_deg)
    q = (points - target) @ probe.rotation.T
    need = np.maximum.reduce([
        probe.fx * np.abs(q[:, 0]) / (fill * width / 2.0) - q[:, 2],
        probe.fy * np.abs(q[:, 1]) / (fill * height / 2.0) - q[:, 2],
        NEAR_MARGIN - q[:, 2],
    ])
    return max(float(np.percentile(need, DISTANCE_QUANTILE)), NEAR_MARGIN)


def _path(n: int, elevations, seed: int, sweep: float, center_az: float, wobble: float):
    """(azimuth, elevation) in radians for n views: rings visited in turn, azimuth sweeping ``sweep``
    radians (centred on ``center_az`` when the sweep is partial), seeded start and jitter."""
    rng = np.random.default_rng(seed)
    els = np.radians(np.asarray(elevations, np.float64))
    full = sweep >= 2 * math.pi - 1e-9
    step = sweep / n if full else sweep / max(n - 1, 1)
    start = rng.uniform(0.0, 2 * math.pi) if full else center_az - sweep / 2.0
    out = []
    for i in range(n):
        az = start + i * step + rng.uniform(-0.2, 0.2) * step
        el = els[i % len(els)] + math.radians(wobble) * math.sin(2 * math.pi * i / n)
        el += math.radians(rng.uniform(-2.0, 2.0))
        out.append((az, float(np.clip(el, -math.radians(85), math.radians(85)))))
    return out


def _split(cams: list[Camera], n_test: int, rig: str) -> RigViews:
    test_idx = set(held_out_indices(len(cams), n_test))
    return RigViews([c for i, c in enumerate(cams) if i not in test_idx],
                    [c for i, c in enumerate(cams) if i in test_idx], rig)


def front_direction(place: Placement) -> np.ndarray:
    """Least-spread principal axis of the content, signed as described in the module docstring."""
    _, vecs = np.linalg.eigh(np.cov((place.points - place.center).T))
    f = vecs[:, 0]
    s = float(f @ place.up)
    if abs(s) < 1e-6:
        s = float(f @ place.horizontal_basis[0])
    return f if s >= 0 else -f


def _forward_directions(place: Placement, front, path) -> list[np.ndarray]:
    f = np.asarray(front, np.float64)
    f = f / np.linalg.norm(f)
    side = np.cross(place.up, f)
    if np.linalg.norm(side) < 1e-6:  # looking straight along up: any perpendicular
        side = np.cross(f, [1.0, 0.0, 0.0] if abs(f[0]) < 0.9 else [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    v = np.cross(f, side)
    dirs = [f + math.tan(a) * side + math.tan(b) * v for a, b in path]
    return [d / np.linalg.norm(d) for d in dirs]


def choose_rig(place: Placement) -> str:
    """``room`` or ``orbit`` for a scene without a table entry (see the module docstring)."""
    d = np.linalg.norm(place.points - place.dense_center, axis=1)
    spread = np.percentile(d, 90) / max(np.percentile(d, 10), 1e-12)
    return "room" if spread >= ROOM_SPREAD and enclosure(place) >= ENCLOSURE_ROOM else "orbit"


def make_rig(name: str, scene: GaussianScene, *, n_train: int = N_TRAIN, n_test: int = N_TEST,
             longest_side: int = LONGEST_SIDE, aspect: float = ASPECT, seed: int = 0, up=None,
             elevations=None, fov_deg: float = FOV_DEG, front=None, rings_above=None) -> RigViews:
    """Build rig ``name`` (one of :data:`RIG_NAMES`) around ``scene``; see the module docstring.

    ``elevations`` (degrees) are the rings of ``orbit``/``room`` and, for ``forward``, the angles across
    the arc (default 0). ``up`` defaults to −y; ``front`` (forward only) to :func:`front_direction`.
    ``rings_above`` (degrees) replaces the rings by a band above the highest one (``forward``: arc
    angles above its highest; views stay within ±85°): the ``shifted`` protocol's held-out views
    (:mod:`harness.views.heldout`).
    """
    if name not in RIG_NAMES:
        raise ValueError(f"unknown rig {name!r}; known: {', '.join(RIG_NAMES)}")
    if n_train < 0 or n_test < 1:
        raise ValueError("need n_train ≥ 0 and n_test ≥ 1")
    place = placement(scene, up=up)
    if name == "auto":
        name = choose_rig(place)
    width, height = image_size(longest_side, aspect)
    n = n_train + n_test
    els = tuple(elevations or _RIG_DEFAULT_ELEVATIONS[name])
    if rings_above:  # a band above the rig's own rings (a shifted protocol's test views)
        els = tuple(max(els) + a for a in rings_above)
    common = {"up": place.up, "width": width, "height": height, "fov_deg": fov_deg}
    if name in ("orbit", "room"):
        dirs = [place.direction(az, el) for az, el in _path(n, els, seed, 2 * math.pi, 0.0, 0.0)]
    if name == "orbit":
        target, points, fill, max_d = place.center, place.points, OBJECT_FILL, None
    elif name == "room":
        target = place.dense_center
        dist = np.linalg.norm(place.points - target, axis=1)
        points = place.points[dist <= np.percentile(dist, 25)]
        fill, max_d = 0.6, 0.5 * float(np.median(dist))
    else:
        f = front_direction(place) if front is None else front
        dirs = _forward_directions(place, f, _path(n, els, seed, math.radians(40.0), 0.0, 5.0))
        target, points, fill, max_d = place.center, place.points, OBJECT_FILL, None
    dist = np.array([fit_distance(target, u, points, fill=fill, **common) for u in dirs])
    dist = np.minimum(np.maximum(dist, np.median(dist)), np.inf if max_d is None else max_d)
    digits = max(3, len(str(n - 1)))  # names sort in path order (RigViews.all)
    cams = [look_from(target, u, float(d), name=f"{name}_{i:0{digits}d}", **common)
            for i, (u, d) in enumerate(zip(dirs, dist))]
    return _split(cams, n_test, name)


def resolve_rig(dataset: str | None, rig: str = "default") -> tuple[str, dict]:
    """(rig name, :func:`make_rig` keywords) of ``rig`` for a scene: ``default`` is the
    :data:`SCENE_RIGS` entry of the named dataset (its rig, up axis, aspect and elevations), ``auto``
    for any other scene; an explicit rig comes with no keywords."""
    if rig not in RIG_CHOICES:
        raise ValueError(f"unknown rig {rig!r}; known: {', '.join(RIG_CHOICES)}")
    if rig != "default":
        return rig, {}
    d = SCENE_RIGS.get(dataset or "")
    if d is None:
        return "auto", {}
    return d.rig, {k: v for k, v in (("up", d.up), ("aspect", d.aspect), ("elevations", d.elevations))
                   if v is not None}


def scene_rig(dataset: str | None, scene: GaussianScene, rig: str = "default", **overrides) -> RigViews:
    """The rig of a scene. ``rig="default"``: the :data:`SCENE_RIGS` entry of the named dataset the
    scene is (its rig, up axis, aspect and elevations), ``auto`` for any other scene. An explicit rig
    (``orbit``, ``room``, ``forward``, ``auto``) uses only what it is given: the same flags give the
    same rig whatever the scene or its file is called. Keyword arguments of :func:`make_rig` that are
    not None override everything (an explicit ``aspect`` wins over the table's)."""
    rig, kwargs = resolve_rig(dataset, rig)
    kwargs.update({k: v for k, v in overrides.items() if v is not None})
    return make_rig(rig, scene, **kwargs)


def training_views(name: str, scene: GaussianScene, *, n_train: int = 16, n_test: int = 12,
                   longest_side: int = 384, seed: int = 0) -> list:
    """The training cameras of the default rig of the scene given by ``name`` (a dataset name or a
    path: :func:`harness.io.datasets.identify`), as ``harness run`` builds them."""
    from harness.io.datasets import identify

    return list(scene_rig(identify(name), scene, n_train=n_train, n_test=n_test, longest_side=longest_side,
                          seed=seed).train)
