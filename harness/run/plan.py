"""The plan of a run: which (scene, frame), cameras, method variants, ratios and views to evaluate.

Stages and their cache keys (every key also holds the code digest of what computes it, and the
config values whose fields declare it: :mod:`harness.run.config.keys`):

* **load**  — per (scene, frame): file digest (+ LOD) -> splat count, SH degree, size model of its .ply.
* **views** — per scene: rig (or camera file digest) + counts, resolution, aspect, seed -> train/test
  cameras. Multi-frame sequences use the rig of their first frame for every frame, so all frames
  are seen from the same held-out views.
* **score** — per (scene, frame, method, resolved params): scores (N,), computed once for all ratios.
  Camera-aware pruners also key on the train cameras and the device.
* **prune** — per (score key, ratio): keep mask (stored by its own digest), τ, counts.
* **render_ref** — per (scene, frame, test view): the unpruned render.
* **metrics** — per (reference render, keep-mask digest): PSNR/SSIM/LPIPS of the pruned render.
  Two methods that keep the same splats share the entry, so the set is rendered once. A view with
  a photo (the ``real`` protocol) also keys on the photo's sha256 and holds the ``gt_`` metrics.
* **gt** — per (reference render, photo digest): the unpruned render against the photo.

**Protocols and training sets.** Each view protocol of the run (:mod:`harness.views.protocols`,
asked by :mod:`harness.run.protocol_views`) gives a scene its held-out views, measured with the
masks of one *training set*: ``rig`` (the scene's own training views: ``rig``, ``shifted``,
``independent`` and every protocol that brings none) or one the protocol brings (``capture``: the
capture's training cameras, the ``real`` protocol). Camera-aware pruners score once per training
set (their score keys hold the cameras); the others score once — their keys do not depend on the
training set, so the second set's entry is the first's.

Scenes are resolved before any work (:func:`harness.run.sources.check_sources`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from harness.core.cameras import COORD_MAX, Camera
from harness.core.extent import MAX_BLUR, blur, check_extent, largest_coordinate
from harness.run.cache import StageCache, digest_json
from harness.run.cache.versions import Versions
from harness.run.config import MethodVariant, RunConfig, SceneSpec
from harness.run.config.keys import key_inputs
from harness.run.scene_views import scene_views
from harness.run.sources import Skip, cameras_missing, resolve_paths
from harness.run.toolkit import Toolkit
from harness.views.protocols import HeldOut


@dataclass
class SceneItem:
    """One (scene, frame) that exists on disk, with its cameras."""

    spec: SceneSpec
    frame: str  # "" for single-file scenes, else the frame file's stem
    path: str
    digest: str  # content digest of the scene file(s) + LOD
    n_splats: int
    sh_degree: int
    rig: str
    train: list[Camera]
    test: list[Camera]
    ply_base: int = 0  # size model of the pruned .ply (harness.io.plysize): base + digits + N·row
    ply_row: int = 0
    #: the held-out views of each protocol of the run that measures the scene, in the config's order
    held: dict[str, HeldOut] = field(default_factory=dict)

    def views(self) -> list[tuple[str, int, Camera]]:
        """(protocol, index within it, camera) of every held-out view, protocol by protocol."""
        return [(proto, v, c) for proto, h in self.held.items() for v, c in enumerate(h.test)]

    def primary_views(self) -> list[Camera]:
        """The held-out views of the run's first protocol that measures the scene (contact sheets, figures)."""
        return next(iter(self.held.values())).test if self.held else self.test

    def train_set(self, protocol: str) -> str:
        """The training set whose masks a protocol's views measure: ``rig`` (the scene's) or the
        protocol's own (``capture``)."""
        h = self.held.get(protocol)
        return h.training_set if h is not None and h.train is not None else "rig"

    def train_sets(self) -> dict[str, list[Camera]]:
        """The training sets of the protocols measured on this item, the scene's own first."""
        out = {"rig": self.train} if any(h.train is None for h in self.held.values()) else {}
        for h in self.held.values():
            if h.train is not None:
                out.setdefault(h.training_set, h.train)
        return out

    def photo(self, protocol: str, view: str) -> tuple[str, str] | None:
        """(photo path, sha256) of a held-out view that has one."""
        h = self.held.get(protocol)
        return h.photos.get(view) if h is not None else None

    def ply_bytes(self, count: int) -> int | None:
        """Bytes of the .ply the harness writes for ``count`` of this frame's splats (None: unknown)."""
        from harness.io.plysize import PlySize

        return PlySize(self.ply_base, self.ply_row)(count) if self.ply_row else None

    @property
    def train_digest(self) -> str:
        return digest_json([c.to_dict() for c in self.train])


class _LazyScene:
    """Loads the scene file on first call only (a fully cached rerun never reads it)."""

    def __init__(self, toolkit: Toolkit, path: str, lod):
        self.toolkit, self.path, self.lod, self.scene = toolkit, path, lod, None

    def __call__(self):
        if self.scene is None:
            self.scene = self.toolkit.load_scene(self.path, self.lod)
        return self.scene


def load_items(config: RunConfig, cache: StageCache, toolkit: Toolkit, versions: Versions,
               base: Path, on_skip=None, on_note=None,
               first_frames: bool = False) -> tuple[list[SceneItem], list[Skip]]:
    """Resolve every scene's files, splat counts and cameras; absent optional scenes become skips,
    absent required ones (gone since :func:`check_sources` passed) errors.

    Scenes are loaded only when a stage needs them (a miss of ``load`` or ``views``), so a rerun
    with everything cached never reads a scene file. Every protocol's checks run first, for every
    scene (:func:`harness.run.protocol_views.check_protocols`), so a bad capture stops the run
    before any work (an :class:`InputError`). A scene no protocol of the run measures is skipped with
    why. ``on_note(spec, text)`` hears what a protocol brings (a capture's views) or why it does not
    measure a scene. ``first_frames``: only each scene's first frame (its views serve every frame).
    """
    from harness.core.errors import InputError
    from harness.run.protocol_views import check_protocols

    check_protocols(config, base, toolkit)
    items, skips = [], []
    for spec in config.scenes:
        frames, missing = resolve_paths(spec, toolkit, base)
        missing = missing or cameras_missing(spec, base)
        try:
            got = [] if missing else _scene_items(spec, frames[:1] if first_frames else frames, config, cache,
                                                  toolkit, versions, base, on_note)
        except _Unmeasured as why:
            missing = str(why)
        except InputError as err:  # a bad file spoils this scene only; the run goes on and exits 1
            skips.append(Skip(spec.name, "", "*", "*", f"cannot use it: {err}", status="error"))
            if on_skip:
                on_skip(spec, f"cannot use it: {err}")
            continue
        if missing:
            skips.append(Skip(spec.name, "", "*", "*", missing, status="skipped" if spec.optional else "error"))
            if on_skip:
                on_skip(spec, missing)
            continue
        items += got
    return items, skips


class _Unmeasured(Exception):
    """No protocol of the run measures a scene (the message says why)."""


def _scene_items(spec, frames, config, cache, toolkit, versions, base, on_note=None) -> list[SceneItem]:
    from harness.run.verify import load_check

    items, views, held = [], None, None
    for frame, path in frames:
        digest = digest_json({"file": cache.files.scene(path), **key_inputs("load", spec)})
        scene = _LazyScene(toolkit, str(path), spec.lod)
        key = cache.key("load", scene=digest, code=versions.reader)
        info = cache.get_json("load", key, check=load_check())
        if info is None or "blur" not in info:  # (entries of older code lack it)
            from harness.io.plysize import ply_size_model

            s = scene()
            size = ply_size_model(s)
            info = {"n_splats": len(s), "sh_degree": int(s.sh_degree), "ply_base": size.base, "ply_row": size.row,
                    "largest_coordinate": largest_coordinate(s), "blur": blur(s)}
            cache.put_json("load", key, info)
        if not info["n_splats"]:  # an error of this scene (exit 1), not of the run
            from harness.core.errors import InputError

            raise InputError(path, "holds no splats: there is nothing to prune or render")
        if info["largest_coordinate"] > COORD_MAX or info["blur"] > MAX_BLUR:  # beyond what the renders hold: an
            # error of this scene (harness.core.extent)
            check_extent(scene(), path)
        if views is None:  # the first frame's views serve the whole sequence
            views = scene_views(spec, scene, path, config.protocol, cache, toolkit, versions, digest, base)
            held = protocol_views(spec, scene, views, config, cache, toolkit, versions, digest, base, on_note)
        rig, train, test = views
        items.append(SceneItem(spec, frame, str(path), digest, info["n_splats"], info["sh_degree"], rig,
                               train, test, info["ply_base"], info["ply_row"], held))
    return items


def protocol_views(spec: SceneSpec, scene, views, config: RunConfig, cache: StageCache, toolkit: Toolkit,
                   versions: Versions, scene_digest: str, base: Path, on_note=None) -> dict[str, HeldOut]:
    """The held-out views of each protocol of the run on a scene (:mod:`harness.run.protocol_views`);
    raises :class:`_Unmeasured` when none measures it."""
    from harness.run import protocol_views as pv

    rig, train, test = views
    req = pv.request(spec, config, toolkit, base, scene=scene, held_out=lambda: list(test),
                     digest=cache.files.digest)
    req.synthetic = req.synthetic and rig not in ("file", "sequence")
    held, why, inputs = {}, {}, key_inputs("protocol_views", config.protocol, spec)
    for proto in config.protocols:
        got, reason = pv.held_out(proto, req, cache, versions.protocol(proto.spec.name), scene_digest, inputs)
        if got is not None:
            held[proto.name] = got
            if on_note and got.source:
                cam = got.test[0]
                on_note(spec, f"{proto.name}: {len(got.test)} held-out views and {len(got.train or [])} training "
                              f"cameras of {got.source} at {cam.width}x{cam.height}"
                              + "".join(f"; {n}" for n in got.notes))
        elif reason:
            why[proto.name] = reason
    if not held:
        names = [p.name for p in config.protocols]
        reasons = "; ".join(f"{k}: {v}" for k, v in why.items())
        raise _Unmeasured(f"the {names[0]} protocol measures it only, and {why.get(names[0], 'it has no views')}"
                          if len(names) == 1 else f"none of the protocols {', '.join(names)} measures it ({reasons})")
    for name, reason in why.items():
        if on_note:
            on_note(spec, f"not measured under {name}: {reason}")
    return held


def variants_for(item: SceneItem, methods: list[MethodVariant], protocol: str | None = None) -> list[MethodVariant]:
    """The method variants measured on ``item`` (their ``scenes``), under ``protocol`` when given."""
    return [m for m in methods if (m.scenes is None or item.spec.name in m.scenes)
            and (protocol is None or m.measures(protocol))]


def training_sets_for(item: SceneItem, mv: MethodVariant) -> dict[str, list]:
    """The item's training sets (:meth:`SceneItem.train_sets`) whose protocols measure ``mv``: a
    variant measured only under ``real`` is not scored on the rig's training views, and vice versa."""
    wanted = {item.train_set(p) for p in item.held if mv.measures(p)}
    return {ts: train for ts, train in item.train_sets().items() if ts in wanted}
