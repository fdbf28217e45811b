"""A scene's own views — a synthetic rig's, a cameras file's or an MPEG sequence's cameras — made
once and kept in the ``views`` stage of the cache, keyed on the scene's digest (or the camera files'
content) and the config values that declare the view keys (:mod:`harness.run.config.keys`).
"""

from __future__ import annotations

from pathlib import Path

from harness.core.cameras import Camera
from harness.run.cache import StageCache
from harness.run.cache.versions import Versions
from harness.run.config import SceneSpec
from harness.run.config.keys import key_inputs
from harness.run.toolkit import Toolkit


def select_test(cams: list[Camera], spec) -> tuple[list[Camera], list[Camera]]:
    """Split cameras from a file: named test views, else every ``test_every``-th (LLFF convention)."""
    if spec.test:
        test = [c for c in cams if c.name in spec.test or Path(c.name).stem in spec.test]
    else:
        test = [c for i, c in enumerate(cams) if i % spec.test_every == 0]
    ids = {id(c) for c in test}
    return [c for c in cams if id(c) not in ids], test


def scene_views(item_spec: SceneSpec, scene, path: Path, protocol, cache: StageCache, toolkit: Toolkit,
                versions: Versions, scene_digest: str, base: Path):
    """(rig name, train, test) for a scene, cached by its inputs."""
    p = protocol
    if item_spec.sequence is not None:
        return _sequence_views(item_spec, cache, versions, base)
    if item_spec.cameras is not None:
        cpath = Path(item_spec.cameras.path)
        cpath = cpath if cpath.is_absolute() else base / cpath
        inputs = key_inputs("file_views", p, item_spec.cameras)
        inputs["source"]["cameras"] = cache.files.digest(cpath)
    else:
        dataset = item_spec.source if item_spec.source and toolkit.resolve_dataset(item_spec.source) else None
        inputs = key_inputs("rig_views", p, item_spec)
        inputs["source"].update(scene=scene_digest, dataset=dataset)
    from harness.run.verify import views_check

    key = cache.key("views", code=versions.rigs, **inputs)
    hit = cache.get_json("views", key, check=views_check())
    if hit is not None:
        return hit["rig"], [Camera.from_dict(c) for c in hit["train"]], [Camera.from_dict(c) for c in hit["test"]]
    if item_spec.cameras is not None:
        cams = [c.resized(p.longest_side) for c in toolkit.load_cameras(str(cpath))]
        train, test = select_test(cams, item_spec.cameras)
        if not test:
            from harness.core.errors import InputError

            raise InputError(cpath, f"none of the held-out views {list(item_spec.cameras.test)} is among its "
                                    f"{len(cams)} cameras ({', '.join(c.name for c in cams[:6])}, ...)")
        rig = "file"
    else:
        rig, train, test = toolkit.make_rig(item_spec.rig, scene(), kind=item_spec.kind, dataset=dataset,
                                            n_train=item_spec.n_train, n_test=item_spec.n_test,
                                            longest_side=p.longest_side, aspect=p.aspect, seed=p.seed)
    cache.put_json("views", key, {"rig": rig, "train": [c.to_dict() for c in train],
                                  "test": [c.to_dict() for c in test]})
    return rig, train, test


def _sequence_views(spec: SceneSpec, cache: StageCache, versions: Versions, base: Path):
    """("sequence", train, test) of an MPEG content folder: every camera at its native size, framed
    as the metric tool frames them; named views (``test``/``test_every``) are held out, else every
    camera is measured and also handed to camera-aware pruners (MPEG scores the capture views)."""
    from harness.io.sequences import find_sequence, sequence_cameras

    root = Path(spec.sequence) if Path(spec.sequence).is_absolute() else base / spec.sequence
    seq, reason = find_sequence(root)
    if seq is None:
        from harness.core.errors import InputError

        raise InputError(root, reason)
    from harness.run.cache.versions import module_versions

    code = [versions.rigs, module_versions(("harness.io.sequences", "harness.io.gscameras", "harness.io.colmap"))]
    inputs = key_inputs("sequence_views", spec)
    inputs["source"]["sequence"] = _sequence_digest(seq, cache)
    key = cache.key("views", code=code, **inputs)
    hit = cache.get_json("views", key)
    if hit is not None:
        return hit["rig"], [Camera.from_dict(c) for c in hit["train"]], [Camera.from_dict(c) for c in hit["test"]]
    train, test = _sequence_split(seq, spec, sequence_cameras(seq, spec.width, spec.height))
    cache.put_json("views", key, {"rig": "sequence", "train": [c.to_dict() for c in train],
                                  "test": [c.to_dict() for c in test]})
    return "sequence", train, test


def _sequence_digest(seq, cache: StageCache) -> dict:
    """What a sequence's views are made of: its camera file(s) by content (the first frame's header
    when it has no camera file)."""
    src = seq.cameras if seq.cameras is not None and seq.cameras.is_file() else None
    digest = {"cameras": cache.files.digest(src) if src else str(seq.cameras),
              "frame0": cache.files.digest(seq.frames[0]) if seq.cameras is None else None}
    if seq.cameras is not None and seq.cameras.is_dir():
        digest["cameras"] = [cache.files.digest(f) for f in sorted(seq.cameras.iterdir()) if f.is_file()]
    return digest


def _sequence_split(seq, spec: SceneSpec, cams: list[Camera]) -> tuple[list[Camera], list[Camera]]:
    """(train, test): the named views held out, else every camera both measured and trained on."""
    if not (spec.test or spec.test_every):
        return cams, cams
    train, test = select_test(cams, spec)
    if not test:
        from harness.core.errors import InputError

        raise InputError(seq.camera_source, f"none of the views {list(spec.test)} is among its {len(cams)} cameras")
    return train, test
