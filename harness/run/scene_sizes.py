"""What a cost estimate knows of each scene before running anything (:mod:`harness.run.estimate`):
its splats per frame and the sizes of its views under every view protocol of the config.

A scene present on this machine is **read** as far as headers go (PLY counts, a ``.splat``'s size,
camera files, a capture's cameras — never a render); an absent one is **assumed**
(:class:`Assumptions`: 32 frames of 1,000,000 splats, the public camera counts of the MPEG sequences).
Each view protocol says the sizes of its views on the scene
(:meth:`harness.views.protocols.Protocol.sizes`): those measured with the scene's own training
views, and those of protocols that bring a training set of their own (``real``: the capture's).
An absent scene is taken to carry no capture; a present one with a bad capture is an error, not an
assumption.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from harness.core.errors import InputError
from harness.run.config import RunConfig, SceneSpec

#: held-out cameras of the MPEG sequences whose count is public (VGSC evaluation scripts: test
#: views 0..20, 0..14, 0..20); other sequences: :data:`DEFAULT_VIEWS`
KNOWN_VIEWS = {"bartender": 21, "breakfast": 15, "cinema": 21}
DEFAULT_VIEWS = 21


@dataclass(frozen=True)
class Assumptions:
    """What an absent scene is taken to be: ``frames`` per sequence (32, a CTC sequence's), ``views``
    cameras (None: :data:`KNOWN_VIEWS` by name, else :data:`DEFAULT_VIEWS`), ``splats`` per frame
    and the native ``size`` (the CTC's 1920×1080)."""

    frames: int = 32
    views: int | None = None
    splats: int = 1_000_000
    size: tuple[int, int] = (1920, 1080)


@dataclass
class OwnViews:
    """A protocol's held-out views (W, H) measured with a training set of its own (``train``), and
    whether they are measured against photos too."""

    protocol: str
    views: list[tuple[int, int]]
    train: list[tuple[int, int]]
    photos: bool = False


@dataclass
class SceneInfo:
    name: str
    status: str                    # "read" or "assumed"
    note: str                      # what was read, or why it is assumed
    splats: list[int]              # per frame
    views: list[tuple[int, int]]   # (W, H) of the held-out views measured with the scene's training views
    train: list[tuple[int, int]]   # (W, H) of the scene's training views, handed to camera-aware pruners
    #: the protocol of each of ``views`` (default: the run's first)
    protocols: list[str] = field(default_factory=list)
    #: the protocols that bring a training set of their own (``real``: the capture's cameras)
    own: list[OwnViews] = field(default_factory=list)
    #: the views as a run makes them, to project (:class:`harness.run.view_coverage.SceneCoverage`;
    #: None: not looked at, or the scene is assumed — its views are taken to see what the calibration's did)
    seen: object = None

    def view_protocols(self, default: str) -> list[str]:
        """The protocol of every held-out view: ``views`` (``default`` where ``protocols`` says none),
        then each of ``own`` in turn."""
        named = list(self.protocols[:len(self.views)]) + [default] * (len(self.views) - len(self.protocols))
        return named + [o.protocol for o in self.own for _ in o.views]

    def every_view(self) -> list[tuple[int, int]]:
        return list(self.views) + [v for o in self.own for v in o.views]

    def every_train(self) -> list[tuple[int, int]]:
        return list(self.train) + [v for o in self.own for v in o.train]


def splat_count(path: Path, lod=None) -> int:
    """Splats in a scene file from its header (PLY) or size (.splat); other formats are read."""
    from harness.io.detect import detect

    kind = detect(path).kind
    if kind in ("ply", "compressed-ply"):
        from harness.io.ply import read_ply_header

        vertex = read_ply_header(path).element("vertex")
        if vertex is not None and kind == "ply":
            return vertex.count
    if kind == "splat":
        from harness.io.splat import SPLAT_RECORD

        return path.stat().st_size // SPLAT_RECORD.itemsize
    from harness.io.scenes import load_scene

    return len(load_scene(path, lod=lod))


def _rig_size(spec: SceneSpec, config: RunConfig, dataset: str | None) -> tuple[int, int]:
    from harness.views import rigs

    aspect = config.protocol.aspect
    if aspect is None and spec.rig == "default" and dataset in rigs.SCENE_RIGS:
        aspect = rigs.SCENE_RIGS[dataset].aspect
    return rigs.image_size(config.protocol.longest_side, aspect or rigs.ASPECT)


def _split(n: int, names: tuple, every: int) -> tuple[int, int]:
    """(train, test) counts of ``n`` cameras split by test names / every k-th (none: all are both)."""
    if names:
        test = min(len(names), n)
    elif every:
        test = math.ceil(n / every)
    else:
        return n, n
    return n - test, test


def _sizes(cams) -> list[tuple[int, int]]:
    return [(c.width, c.height) for c in cams]


def _own_views(spec, config, toolkit, base, dataset) -> tuple[list, list]:
    """(held-out, training) sizes of the scene's own views: its MPEG content's, its camera file's,
    or ``n_test`` and ``n_train`` views of its rig."""
    from harness.run.scene_views import select_test

    if spec.sequence is not None:
        from harness.io.sequences import find_sequence, sequence_cameras

        root = Path(spec.sequence) if Path(spec.sequence).is_absolute() else base / spec.sequence
        cams = sequence_cameras(find_sequence(root)[0], spec.width, spec.height)
        train, test = select_test(cams, spec) if spec.test or spec.test_every else (cams, cams)
        return _sizes(test), _sizes(train)
    if spec.cameras is not None:
        path = Path(spec.cameras.path) if Path(spec.cameras.path).is_absolute() else base / spec.cameras.path
        cams = [c.resized(config.protocol.longest_side) for c in toolkit.load_cameras(str(path))]
        train, test = select_test(cams, spec.cameras)
        return _sizes(test), _sizes(train)
    size = _rig_size(spec, config, dataset)
    return [size] * spec.n_test, [size] * spec.n_train


def _protocol_views(spec, config, toolkit, base, own: tuple[list, list], capture: bool = True) -> dict:
    """The :class:`SceneInfo` fields ``views``, ``train``, ``protocols`` and ``own`` of a scene: each
    protocol's view sizes (:meth:`harness.views.protocols.Protocol.sizes`), given the scene's own
    (``own``: held-out, training); without ``capture`` the scene is taken to carry none. A bad
    capture is an error, not an assumption."""
    from harness.run.protocol_views import request

    req = request(spec, config, toolkit, base, own_sizes=lambda: own[0])
    if not capture:
        req.capture = None
    views, protocols, mine = [], [], []
    for proto in config.protocols:
        s = proto.sizes(req)
        if s is None or not s.test:
            continue
        if s.train is None:
            views += s.test
            protocols += [proto.name] * len(s.test)
        else:
            mine.append(OwnViews(proto.name, s.test, s.train, s.photos))
    return {"views": views, "train": own[1] if views else [], "protocols": protocols, "own": mine}


def _assumed(spec, config, assume: Assumptions, dataset, reason: str) -> SceneInfo:
    from harness.run.toolkit import Toolkit

    frames = 1 if spec.source is not None else assume.frames
    if spec.sequence is None and spec.cameras is None:  # a rig: its views need no scene
        own = _own_views(spec, config, None, Path("."), dataset)
        return SceneInfo(spec.name, "assumed", f"{reason}; assumed {frames} frame(s) of {assume.splats:,} splats",
                         [assume.splats] * frames,
                         **_protocol_views(spec, config, Toolkit(), Path("."), own, capture=False))
    n = assume.views or next((v for k, v in KNOWN_VIEWS.items() if k in spec.name.lower()), DEFAULT_VIEWS)
    if spec.sequence is not None:
        size = (spec.width, spec.height) if spec.width else assume.size
        n_train, n_test = _split(n, spec.test, spec.test_every)
    else:
        from harness.views import rigs

        size = rigs.image_size(config.protocol.longest_side, config.protocol.aspect or rigs.ASPECT)
        n_train, n_test = _split(n, spec.cameras.test, spec.cameras.test_every)
    note = (f"{reason}; assumed {frames} frame(s) × {assume.splats:,} splats, {n} cameras at "
            f"{size[0]}×{size[1]} ({n_test} measured, {n_train} for training)")
    return SceneInfo(spec.name, "assumed", note, [assume.splats] * frames,
                     **_protocol_views(spec, config, Toolkit(), Path("."), ([size] * n_test, [size] * n_train),
                                       capture=False))


def scene_info(spec: SceneSpec, config: RunConfig, assume: Assumptions, toolkit=None, base: Path | None = None):
    """A scene as the estimate sees it: read (file headers, camera files) when present, else assumed."""
    from harness.run.sources import cameras_missing, resolve_paths
    from harness.run.toolkit import Toolkit

    toolkit, base = toolkit or Toolkit(), Path(base or ".")
    dataset = spec.source if spec.source and toolkit.resolve_dataset(spec.source) else None
    frames, reason = resolve_paths(spec, toolkit, base)
    reason = reason or cameras_missing(spec, base)
    if not reason:
        try:
            splats = [splat_count(Path(p), spec.lod) for _, p in frames]
            own = _own_views(spec, config, toolkit, base, dataset)
        except InputError as err:
            reason = f"cannot read it ({err})"
        else:
            return SceneInfo(spec.name, "read", f"{len(frames)} frame(s) read", splats,
                             **_protocol_views(spec, config, toolkit, base, own))
    return _assumed(spec, config, assume, dataset, reason)
