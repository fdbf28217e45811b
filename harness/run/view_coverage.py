"""What each view of a study sees, for the cost model of :mod:`harness.run.estimate`.

A GL render's CPU time does not follow the scene's splat count and the image's pixels alone: a view
from inside a room (bonsai-7k) projects every splat but sorts and draws only the third in front of
it, and a few large splats (luigi) cover each pixel hundreds of times. Per view, from its camera:

* ``front`` — the fraction of the splats in front of the camera (``z > NEAR_Z``: projected, their
  2-D covariances computed);
* ``visible`` — the fraction drawn (their ±3σ box on the image and ``o ≥ 1/255``: coloured, sorted,
  packed, rasterised);
* ``overdraw`` — ``F / (W·H)``, the drawn splats' footprints (their ±r boxes, ``r`` the renderer's
  3σ radius, clipped to the image) summed, per image pixel: the fragments llvmpipe shades.

Computed by :func:`renderers.projection.project_arrays` itself, on a seeded sample of at most
:data:`SAMPLE` splats (the fractions and the footprint sum scaled up are unbiased; the views of a
multi-frame sequence are the first frame's). ``harness bench calibrate`` measures the costs per
front splat, visible splat, fragment and image pixel on one view whose coverage this module
computes the same way (:func:`coverage` of the whole scene), so the two meet on one definition.

The views are the run's own: :func:`scene_views` makes them as a run does (the rig, every protocol's
held-out views, a capture's cameras) in a throw-away cache, plus the cameras render-based scoring
draws (a camera-aware pruner's training views, a virtual rig's synthesised ones), each at the size
it is drawn at.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: splats projected per view (a seeded sample of the scene)
SAMPLE = 20_000


@dataclass(frozen=True)
class Coverage:
    """What one view sees (module docstring): fractions of the scene's splats and fragments per pixel."""

    front: float
    visible: float
    overdraw: float


def footprint(means2d: np.ndarray, radii: np.ndarray, width: int, height: int) -> float:
    """Σ of the splats' ±r boxes around their centres, clipped to the ``width × height`` image (pixels)."""
    m, r = np.asarray(means2d, np.float64), np.asarray(radii, np.float64).reshape(-1)
    w = np.clip(m[:, 0] + r, 0, width) - np.clip(m[:, 0] - r, 0, width)
    h = np.clip(m[:, 1] + r, 0, height) - np.clip(m[:, 1] - r, 0, height)
    return float((w * h).sum())


def coverage(scene, camera, total: int | None = None) -> Coverage:
    """The :class:`Coverage` of ``camera`` on ``scene`` (a sample of a scene of ``total`` splats, or the
    whole of it): projected as the GL renderer projects, the splats with ``o < 1/255`` left out as it
    packs them."""
    from renderers.projection import NEAR_Z, project_arrays

    n = len(scene)
    if not n:
        return Coverage(0.0, 0.0, 0.0)
    scale = (total or n) / n  # a sample's footprints stand for the whole scene's
    z = np.asarray(scene.means, np.float64) @ camera.rotation[2] + camera.translation[2]
    p = project_arrays(scene, camera)
    drawn = np.asarray(p.opacities, np.float64).reshape(-1) >= 1.0 / 255.0
    px = camera.width * camera.height
    area = footprint(np.asarray(p.means2d)[drawn], np.asarray(p.radii)[drawn], camera.width, camera.height)
    return Coverage(float((z > NEAR_Z).sum()) / n, float(drawn.sum()) / n, scale * area / px)


def sample(scene, seed: int = 0):
    """At most :data:`SAMPLE` of ``scene``'s splats, drawn with ``seed`` (the scene itself when smaller)."""
    n = len(scene)
    if n <= SAMPLE:
        return scene
    return scene.subset(np.sort(np.random.default_rng(seed).choice(n, SAMPLE, replace=False)))


@dataclass
class SceneCoverage:
    """The views of one scene as a run makes them, and a sample of its first frame to project."""

    sample: object
    #: splats of the scene the sample is drawn from (its first frame)
    total: int
    views: dict[str, list] = field(default_factory=dict)  # protocol -> its held-out cameras
    train: dict[str, list] = field(default_factory=dict)  # protocol -> the training cameras its masks come from
    #: repr(placement) -> the cameras of the virtual rig such a method places on the whole scene (a sample
    #: may read as another shape: bonsai-7k's 20,000 splats look like an object, its 1.16 M like a room)
    rigs: dict[str, list] = field(default_factory=dict)
    _memo: dict = field(default_factory=dict)

    def of_views(self, protocol: str) -> list[Coverage]:
        """The coverage of each held-out view of ``protocol`` (none: the scene has no such views)."""
        return self._cover(self.views.get(protocol, []), 0)

    def of_training(self, protocol: str, longest_side: int = 0) -> list[Coverage]:
        """The coverage of the training views behind ``protocol``'s masks, resized to ``longest_side``."""
        return self._cover(self.train.get(protocol, []), longest_side)

    def of_virtual_rig(self, params) -> list[Coverage] | None:
        """The coverage of the views a virtual rig with ``params`` synthesises for this scene (its
        ``views`` cameras at its ``resolution``; None: not made, as for a method not scored here)."""
        cams = self.rigs.get(repr(_placement(params)))
        return None if cams is None else self._cover(cams, 0)

    def _cover(self, cams: list, side: int) -> list[Coverage]:
        """The coverage of ``cams`` resized to ``side`` (0: as they are), once per camera list (the
        protocols that share a training set share its list)."""
        key = (tuple(map(id, cams)), side)
        if key not in self._memo:
            self._memo[key] = [coverage(self.sample, c.resized(side) if side else c, self.total) for c in cams]
        return self._memo[key]


def scene_views(config, base: Path | None = None, toolkit=None) -> dict[str, SceneCoverage]:
    """Every present scene of ``config`` with the views a run of it makes (module docstring), by
    scene name; absent scenes are left out (their estimate assumes full coverage)."""
    from harness.run.cache import StageCache
    from harness.run.cache.versions import Versions
    from harness.run.plan import load_items
    from harness.run.toolkit import Toolkit

    toolkit = toolkit or Toolkit()
    out: dict[str, SceneCoverage] = {}
    with tempfile.TemporaryDirectory(prefix="harness-plan-") as tmp:
        items, _ = load_items(config, StageCache(tmp), toolkit, Versions.of(toolkit), Path(base or "."),
                              first_frames=True)  # a sequence's first frame's views serve every frame
        for item in items:
            sets, scene = item.train_sets(), toolkit.load_scene(item.path, item.spec.lod)
            out[item.spec.name] = SceneCoverage(
                sample(scene), item.n_splats, {p: list(h.test) for p, h in item.held.items()},
                {p: list(sets.get(item.train_set(p), [])) for p in item.held}, _rigs(config, item.spec.name, scene))
    return out


def _rigs(config, name: str, scene) -> dict[str, list]:
    """The virtual rigs the methods of ``config`` measured on scene ``name`` place (rig-shaped params:
    :func:`is_rig_shaped`), by ``repr`` of their placement (:func:`_placement`)."""
    from methods.virtualrig import virtual_cameras

    wanted = {repr(p): p for p in (_placement(m.params) for m in config.methods
                                   if (m.scenes is None or name in m.scenes) and is_rig_shaped(m.params))}
    return {k: list(virtual_cameras(scene, p)[1]) for k, p in wanted.items()}


def _placement(params):
    """The :class:`~methods.virtualrig.VirtualRigParams` part of a rig-shaped method's params (what
    places its rig: ``virtual-rig`` and ``betadesc-vr`` with the same geometry share one rig)."""
    from dataclasses import fields

    from methods.virtualrig import VirtualRigParams

    return VirtualRigParams(**{f.name: getattr(params, f.name) for f in fields(VirtualRigParams)})


def look(infos, config, base: Path | None = None, toolkit=None) -> None:
    """Give each read scene of ``infos`` (:class:`~harness.run.scene_sizes.SceneInfo`) its views
    (``seen``), as :func:`scene_views` makes them."""
    if not any(i.status == "read" for i in infos):
        return
    seen = scene_views(config, base, toolkit)
    for info in infos:
        if info.status == "read":
            info.seen = seen.get(info.name)


def is_rig_shaped(params) -> bool:
    """Whether a camera-free method's parameters (a mapping or a params object) say it renders a
    virtual rig of its own (:mod:`methods.virtualrig`: ``rig``, ``views`` and ``resolution``)."""
    get = params.get if isinstance(params, dict) else lambda k: getattr(params, k, None)
    return all(get(k) is not None for k in ("rig", "views", "resolution"))
