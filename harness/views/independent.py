"""The ``independent`` held-out protocol: random views from a camera distribution defined without
the training rig's path, rings and field of view, and without any virtual rig, so that no pruner
(camera-aware or camera-free) can have been fitted to it.

What it shares with the scene's rig is only *where a camera can physically be*: the scene kind and
up axis of :data:`harness.views.rigs.SCENE_RIGS` (else the rigs' ``auto`` choice) and the robust
placement statistics of :mod:`harness.views.placement`. The generator is
``numpy.random.default_rng((seed, h))`` with ``h`` 63 bits of the sha256 of the splat centres:
seeded per scene, the same views for the same scene. Each view draws, in this order:

* **field of view** across the long side: uniform 30°–80° (the rig's is 60°, ``shifted``'s 36°);
* **close-up or not**: a close-up with probability 1/4;
* **direction** ``u`` (from the target towards the camera), by kind:
  ``orbit`` uniform over the sphere's band of elevations −10°…70° about up (uniform in sin(el));
  ``forward`` uniform in the 35° cone around the rigs' front direction (the rig's arc spans ±20°);
  ``room`` azimuth uniform, elevation uniform 5°–50°;
* **target and distance**: ``orbit``/``forward``: the robust centre plus an offset uniform in the
  ball of 0.15·radius, at the distance where the content fills a uniform 60–100 % of the frame
  (:func:`harness.views.rigs.fit_distance`); ``room``: the dense centre plus an offset in the ball of
  0.1·m, from a uniform 15–50 % of m away (m: median content distance to the dense centre).
* **close-up**: the target is instead a content point (uniform over the opacity-weighted sample
  within the median distance of the centre), seen along normalise(u + outward) (outward: from the
  centre to that point) from a uniform 35–60 % of the regular distance, never closer than
  :data:`MIN_CLOSE` (the renderers cull splats nearer than 0.2, graphdeco's near plane).
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from harness.core.cameras import Camera
from harness.core.scene import GaussianScene
from harness.views import rigs
from harness.views.placement import Placement, placement

FOV_RANGE = (30.0, 80.0)
CLOSE_UP_SHARE = 0.25
ORBIT_ELEVATIONS = (-10.0, 70.0)
FORWARD_CONE = 35.0
ROOM_ELEVATIONS = (5.0, 50.0)
FILL_RANGE = (0.6, 1.0)
CLOSE_RANGE = (0.35, 0.6)
MIN_CLOSE = 0.6


def scene_seed(scene: GaussianScene, seed: int) -> tuple[int, int]:
    """(seed, 63 bits of the sha256 of the splat centres): the generator's seed for this scene."""
    digest = hashlib.sha256(np.ascontiguousarray(scene.means, np.float32).tobytes()).digest()
    return int(seed), int.from_bytes(digest[:8], "little") >> 1


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-12)


def _ball(rng, radius: float) -> np.ndarray:
    """A point uniform in the ball of ``radius`` about the origin."""
    return _unit(rng.standard_normal(3)) * radius * rng.uniform() ** (1.0 / 3.0)


def _band(rng, place: Placement, lo_deg: float, hi_deg: float) -> np.ndarray:
    """A direction uniform over the sphere's area between elevations ``lo_deg`` and ``hi_deg``."""
    s = rng.uniform(math.sin(math.radians(lo_deg)), math.sin(math.radians(hi_deg)))
    return place.direction(rng.uniform(0.0, 2.0 * math.pi), math.asin(s))


def _cone(rng, axis: np.ndarray, half_deg: float) -> np.ndarray:
    """A direction uniform over the spherical cap of half-angle ``half_deg`` around ``axis``."""
    cos_t = rng.uniform(math.cos(math.radians(half_deg)), 1.0)
    phi = rng.uniform(0.0, 2.0 * math.pi)
    a = _unit(axis)
    e1 = _unit(np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0]))
    e2 = np.cross(a, e1)
    sin_t = math.sqrt(1.0 - cos_t * cos_t)
    return cos_t * a + sin_t * (math.cos(phi) * e1 + math.sin(phi) * e2)


def independent_views(dataset: str | None, scene: GaussianScene, rig: str = "default", *, n_test: int,
                      longest_side: int, aspect: float | None = None, seed: int = 0) -> list[Camera]:
    """``n_test`` views of the independent distribution (module docstring), named ``independent_<i>``."""
    kind, kw = rigs.resolve_rig(dataset, rig)
    place = placement(scene, up=kw.get("up"))
    if kind == "auto":
        kind = rigs.choose_rig(place)
    width, height = rigs.image_size(longest_side, aspect or kw.get("aspect") or rigs.ASPECT)
    rng = np.random.default_rng(scene_seed(scene, seed))
    front = rigs.front_direction(place) if kind == "forward" else None
    dist_c = np.linalg.norm(place.points - place.center, axis=1)
    close_pool = place.points[dist_c <= np.median(dist_c)]
    m_room = float(np.median(np.linalg.norm(place.points - place.dense_center, axis=1)))
    cams = []
    for i in range(n_test):
        fov = rng.uniform(*FOV_RANGE)
        close = rng.uniform() < CLOSE_UP_SHARE
        common = {"up": place.up, "width": width, "height": height, "fov_deg": fov}
        if kind == "room":
            u = _band(rng, place, *ROOM_ELEVATIONS)
            target = place.dense_center + _ball(rng, 0.1 * m_room)
            d = rng.uniform(0.15, 0.5) * m_room
        else:
            u = _band(rng, place, *ORBIT_ELEVATIONS) if kind == "orbit" else _cone(rng, front, FORWARD_CONE)
            target = place.center + _ball(rng, 0.15 * place.radius)
            d = rigs.fit_distance(target, u, place.points, fill=rng.uniform(*FILL_RANGE), **common)
        if close:
            target = close_pool[rng.integers(len(close_pool))]
            u = _unit(u + _unit(target - (place.dense_center if kind == "room" else place.center)))
            d = max(rng.uniform(*CLOSE_RANGE) * d, MIN_CLOSE)
        cams.append(rigs.look_from(target, u, float(d), name=f"independent_{i:03d}", **common))
    return cams
