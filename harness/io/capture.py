"""Captures: the real cameras a scene was trained from, their train / held-out split, the photos.

A scene may carry a capture (config ``scenes[i].capture``)::

    capture: {cameras: cams.json, images: photos/, split: split.json, transform: transform.json}

* ``cameras``: any camera file :func:`harness.io.cameras.load_cameras` reads, at the capture's
  native size; ``transform`` (optional): a similarity, or a chain of them, from the camera file's
  frame into the splat file's (:mod:`harness.io.similarity`).
* The held-out views: ``split`` (a JSON object ``{"test": [names], "train": [names]}``), or
  ``test: [names]``, or ``test_every: k`` (every k-th camera in name order, the LLFF convention).
  Training views: the split's ``train`` list, else every camera not held out.
* ``images``: the photos, matched to the held-out cameras by name (:mod:`harness.io.photos`).

The named scenes ``bonsai-7k`` and ``bonsai-7k-mini`` carry the capture ``bonsai-capture`` without
any config (``capture: false`` turns it off): :data:`SCENE_CAPTURES`, whose manifest
(``manifests/bonsai_capture.json``) pins the origin (a public commit), the licence, the sha256 of
every file used, the split and each scene's transform (fitted by this project — the only derived
data the package ships; the photos and the camera file are read from the mirror folder or a
``harness fetch``-ed copy, never from the repository). Cameras are derived from the pinned camera
file + transform on every use; every file is verified against its pinned sha256 when used.

The ``real`` view protocol (:mod:`harness.views.heldout`) measures the held-out cameras of a
scene's capture against the photos; camera-aware pruners train on the capture's training cameras
under it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from harness.core import paths
from harness.core.cameras import Camera
from harness.core.errors import InputError

_MANIFESTS = Path(__file__).with_name("manifests")
#: named scenes (harness.io.datasets) -> the named capture they were trained from
SCENE_CAPTURES = {"bonsai-7k": "bonsai-capture", "bonsai-7k-mini": "bonsai-capture"}
CAPTURES = {"bonsai-capture": "bonsai_capture.json"}


@dataclass(frozen=True)
class CaptureSpec:
    cameras: str
    images: str
    split: str | None = None
    test: tuple[str, ...] = ()
    test_every: int = 0
    transform: str | None = None
    named: str | None = None   # a named capture: paths are inside its folder, the rest is in its manifest
    scene: str | None = None   # the named scene whose transform applies


@dataclass
class Capture:
    source: str                       # what it is, for messages
    train: list[Camera]               # splat frame, native size
    test: list[Camera]                # splat frame, native size, name order
    photos: dict[str, Path]           # held-out camera name -> photo
    digests: dict[str, str]           # held-out camera name -> sha256 of its photo
    photo_size: tuple[int, int]
    notes: list[str] = field(default_factory=list)


# --------------------------------------------------------------------------- named captures
@lru_cache(maxsize=None)
def manifest(name: str) -> dict:
    return json.loads((_MANIFESTS / CAPTURES[name]).read_text())


def fetched_root(name: str) -> Path:
    return paths.data_dir() / manifest(name)["disk_name"]


def mirror_root(name: str) -> Path:
    return paths.shared_data_dir() / manifest(name)["disk_name"]


def capture_root(name: str) -> Path | None:
    """The fetched copy, else the mirror folder's, else None."""
    for root in (fetched_root(name), mirror_root(name)):
        if root.is_dir():
            return root
    return None


def missing_reason(name: str) -> str:
    m = manifest(name)
    return (f"capture {name!r} is not on this machine (looked in {fetched_root(name)} and the mirror folder "
            f"{mirror_root(name)}); `harness fetch {name}` downloads it from {m['base_url']} ({m['license']})")


def named_spec(scene: str) -> CaptureSpec | None:
    """The capture a named scene carries, or None."""
    name = SCENE_CAPTURES.get(scene)
    if name is None:
        return None
    m = manifest(name)
    return CaptureSpec(cameras=m["cameras"], images=m["images"], named=name, scene=scene)


def describe(spec: CaptureSpec) -> str:
    return f"capture {spec.named!r} of {spec.scene}" if spec.named else f"capture {spec.cameras}"


# --------------------------------------------------------------------------- loading
def _resolve(spec: CaptureSpec, base: Path) -> tuple[Path, Path]:
    if spec.named:
        root = capture_root(spec.named)
        if root is None:
            raise InputError(spec.named, missing_reason(spec.named))
        return root / spec.cameras, root / spec.images
    rel = lambda p: Path(p) if Path(p).is_absolute() else Path(base) / p  # noqa: E731
    return rel(spec.cameras), rel(spec.images)


def _transform(spec: CaptureSpec, base: Path):
    from harness.io.similarity import parse_chain

    if spec.named:
        return parse_chain(manifest(spec.named)["transforms"][spec.scene], f"{spec.named} manifest")
    if spec.transform is None:
        return None
    from harness.io.safe import read_json

    path = Path(spec.transform) if Path(spec.transform).is_absolute() else Path(base) / spec.transform
    return parse_chain(read_json(path, "json", "transform file"), path)


def _split(spec: CaptureSpec, cams: list[Camera], base: Path) -> tuple[list[Camera], list[Camera]]:
    """(train, test) cameras per the spec; a name the camera file lacks is one line."""
    from harness.core.suggest import did_you_mean
    from harness.io.photos import photo_stem

    by_name = {photo_stem(c.name): c for c in cams}
    test_names, train_names, source = _split_names(spec, sorted(by_name), base)
    for names in (test_names, train_names or []):
        unknown = [n for n in names if photo_stem(n) not in by_name]
        if unknown:
            raise InputError(source, f"names {len(unknown)} view(s) the camera file does not have: "
                                     f"{unknown[0]!r}{did_you_mean(photo_stem(unknown[0]), by_name)}"
                                     f"{', ...' if len(unknown) > 1 else ''} ({len(cams)} cameras in {spec.cameras})")
    test = sorted((by_name[photo_stem(n)] for n in dict.fromkeys(test_names)), key=lambda c: c.name)
    held = {c.name for c in test}
    if not test:
        raise InputError(source, "no held-out views")
    if train_names is None:
        return [c for c in cams if c.name not in held], test
    both = [n for n in train_names if by_name[photo_stem(n)].name in held]
    if both:
        raise InputError(source, f"{both[0]!r} is both a training and a held-out view")
    return [by_name[photo_stem(n)] for n in dict.fromkeys(train_names)], test


def _split_names(spec: CaptureSpec, names: list[str], base: Path) -> tuple[list[str], list[str] | None, object]:
    """(held-out names, training names or None for "every other camera", where they were given):
    a named capture's manifest, a split file, ``test:`` names, or every ``test_every``-th of the
    camera ``names`` in sorted order."""
    if spec.named:
        m = manifest(spec.named)
        return m["split"]["test"], m["split"]["train"], f"{spec.named} manifest"
    if spec.split is not None:
        from harness.io.safe import read_json

        source = Path(spec.split) if Path(spec.split).is_absolute() else Path(base) / spec.split
        d = read_json(source, "json", "split file")
        ok = lambda v: isinstance(v, list) and all(isinstance(x, str) for x in v)  # noqa: E731
        if not isinstance(d, dict) or not ok(d.get("test")) or ("train" in d and not ok(d["train"])):
            raise InputError(source, 'expected {"test": [view names], "train": [view names]} (train optional)')
        return d["test"], d.get("train"), source
    if spec.test:
        return list(spec.test), None, "capture.test"
    return [n for i, n in enumerate(names) if i % spec.test_every == 0], None, "capture.test_every"


def load_capture(spec: CaptureSpec, base: Path = Path("."), digest=None) -> Capture:
    """Cameras (in the splat frame), split, photos and their digests of a capture; every problem is
    one :class:`InputError`. ``digest(path) -> sha256`` (default: read the file) hashes what is used;
    a named capture's files must match their pinned sha256."""
    from harness.io.cameras import load_cameras
    from harness.io.photos import check_photos, match_photos

    digest = digest or _sha256
    cam_path, img_dir = _resolve(spec, base)
    pinned = {rel: sha for rel, (_, _, sha) in manifest(spec.named)["files"].items()} if spec.named else {}
    root = cam_path.parent if spec.named else None

    def verified(path: Path) -> str:
        d = digest(path)
        want = pinned.get(path.relative_to(root).as_posix()) if root is not None else None
        if root is not None and d != want:
            raise InputError(path, f"sha256 {d[:16]}... differs from the pinned {str(want)[:16]}... of {spec.named} "
                                   f"(a damaged or different copy); `harness fetch {spec.named}` fetches it again")
        return d

    verified(cam_path)
    cams = load_cameras(cam_path)
    move = _transform(spec, base)
    if move is not None:
        cams = [move.camera(c) for c in cams]
    train, test = _split(spec, cams, base)
    photos = match_photos(test, img_dir, cam_path)
    # a named capture's photos are checked byte for byte against their pinned sha256 below; any
    # other capture's are decoded once here, so a damaged one fails before any work (37 photos: ~4 s)
    size = check_photos(photos, {c.name: c for c in test}, decode=not spec.named)
    digests = {name: verified(p) for name, p in photos.items()}
    notes = [manifest(spec.named)["caveats"]] if spec.named else []
    return Capture(describe(spec), train, test, photos, digests, size, notes)


def protocol_views(capture: Capture, n_test: int | None, longest_side: int):
    """(train, test, side) of the ``real`` protocol: cameras at ``longest_side`` capped at the photos'
    long side (a photo is never upsampled), held-out views the first ``n_test`` by name (None: all)."""
    side = min(int(longest_side), max(capture.photo_size))
    test = capture.test[:n_test] if n_test else capture.test
    return [c.resized(side) for c in capture.train], [c.resized(side) for c in test], side


def _sha256(path: Path) -> str:
    from harness.io.datasets import sha256_file

    return sha256_file(path)
