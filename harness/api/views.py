"""Which views to render: :func:`cameras` (``harness.cameras``) and :func:`views`, the rule of
``harness render`` (its module docstring has the whole rule; in short):

* a camera file (``cameras=``) is rendered every camera as given, unless ``split`` picks the 3DGS
  ``llffhold`` split (test = every 8th view, i % 8 == 0); so are the cameras embedded in the
  scene's header when no rig is asked for;
* else a synthetic rig (``rig``: orbit, room, forward, auto; ``default`` the scene's own: a named
  dataset's rig when the scene is that dataset or was pruned from it, else auto), built from the
  arguments alone (``up``, ``aspect``, ``n_train``/``n_test``, ``seed``, ``longest_side``) and
  fitted to the content, its held-out ``test`` views unless ``split`` says otherwise.

Image sizes come from the arguments only, so two scenes rendered with the same arguments have the
same sizes and their images compare.
"""

from __future__ import annotations

import math

import numpy as np

from harness.core.errors import InputError

#: the 3DGS hold-out: every LLFF_HOLD-th camera of a file is a test view
LLFF_HOLD = 8


def _triple(value, name: str):
    """Three finite numbers from ``"X,Y,Z"`` or a sequence (None passes)."""
    if value is None:
        return None
    try:
        vals = tuple(float(v) for v in (value.split(",") if isinstance(value, str) else value))
    except (TypeError, ValueError):
        vals = ()
    if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
        raise InputError(name, f"expected three numbers X,Y,Z, got {value!r}")
    return vals


def _split_llff(cams):
    return (
        [c for i, c in enumerate(cams) if i % LLFF_HOLD != 0],
        [c for i, c in enumerate(cams) if i % LLFF_HOLD == 0],
    )


def _position_keys(scene) -> np.ndarray:
    """One 64-bit key per splat from the exact bits of its position (a pruned file keeps them)."""
    bits = np.ascontiguousarray(scene.means, dtype=np.float32).view(np.uint32).astype(np.uint64)
    k = bits[:, 0] * np.uint64(0x9E3779B97F4A7C15)
    k ^= bits[:, 1] * np.uint64(0xC2B2AE3D27D4EB4F) + (k >> np.uint64(29))
    k ^= bits[:, 2] * np.uint64(0x165667B19E3779F9) + (k >> np.uint64(31))
    return k


def source_dataset(arg: str, scene):
    """(dataset name, the scene its rig is fitted to, how it was recognised) or None: the named
    dataset ``scene`` is (``arg``: its name or path), or was pruned from."""
    from harness.io.datasets import SCENES, identify, scene_path
    from harness.io.scenes import load_scene

    name = identify(arg) if arg else None
    if name is not None:
        return name, scene, f"the {name} dataset's own"
    if len(scene) == 0:  # the empty set is a subset of every dataset: it was pruned from none of them
        return None
    keys = None
    for name in SCENES:
        path = scene_path(name)
        if not path.exists():
            continue
        data = load_scene(path)
        if len(data) < len(scene) or data.sh_degree != scene.sh_degree:
            continue
        keys = _position_keys(scene) if keys is None else keys
        if np.isin(keys, _position_keys(data)).all():
            return name, data, f"the {name} dataset's own, fitted to {name}: this scene's splats are a subset of it"
    return None


def views(scene, *, cameras=None, rig: str | None = None, split: str | None = None, longest_side: int | None = None,
          n_train: int | None = None, n_test: int | None = None, seed: int = 0, aspect: float | None = None,
          up=None, name: str | None = None) -> tuple[str, list]:
    """(where the views came from, the cameras) for ``scene`` (a loaded scene; ``name`` the name or
    path it was given by, default the file it was read from), per the module docstring: the checks,
    then a camera file's (or the scene's embedded) cameras, else a rig fitted to the scene."""
    from harness.core.extent import check_extent
    from harness.io.cameras import embedded_cameras, load_cameras

    name = name or scene.meta.source
    up = _check_options(longest_side, split, rig, up)
    check_extent(scene, name or "scene")
    file_cams = load_cameras(cameras) if cameras else None
    if file_cams is None and rig in (None, "default"):
        file_cams = embedded_cameras(scene) or None
    if file_cams is not None:
        origin = str(cameras) if cameras else f"{scene.meta.source or name} (embedded cameras)"
        cams = [c.resized(longest_side) for c in file_cams] if longest_side else file_cams
        if split is None:  # used as given
            return f"{origin}, every camera", cams
        origin, selected = _file_split(origin, cams, split)
    else:
        split = split or "test"
        origin, selected = _rig_views(scene, name, rig or "default", split, longest_side=longest_side,
                                      n_train=n_train, n_test=n_test, seed=seed, aspect=aspect, up=up)
    if not selected:
        raise InputError("split", f"the {split!r} split has no views")
    return origin, selected


def _check_options(longest_side, split, rig, up):
    """The options' one-line errors (before any file is read); returns ``up`` as a triple or None."""
    from harness.core.arguments import optional, whole
    from harness.core.cameras import MAX_SIDE
    from harness.views.rigs import RIG_CHOICES

    optional(whole, longest_side, "longest_side", 1, MAX_SIDE)  # pixels, up to the maximum render size
    if split not in (None, "test", "train", "all"):
        raise InputError("split", f"must be test, train or all, got {split!r}")
    if rig is not None and rig not in RIG_CHOICES:
        raise InputError("rig", f"unknown rig {rig!r}; known: {', '.join(RIG_CHOICES)}")
    up = _triple(up, "up")
    if up is not None and not any(up):
        raise InputError("up", "must be a non-zero direction")
    return up


def _file_split(origin: str, cams: list, split: str) -> tuple[str, list]:
    """A camera file's ``split`` (LLFF hold-out: every :data:`LLFF_HOLD`-th view is a test view)."""
    train, test = _split_llff(cams)
    selected = {"test": test, "train": train, "all": cams}[split]
    return origin + f", {split} split (every {LLFF_HOLD}th view is a test view)", selected


def _rig_views(scene, name, rig: str, split: str, *, longest_side, n_train, n_test, seed, aspect, up):
    """(origin, the ``split`` views) of a rig fitted to ``scene`` (``default``: its dataset's rig
    when the scene is, or is a subset of, a known dataset; else ``auto``)."""
    from harness.core.arguments import number, optional, whole
    from harness.views.rigs import ASPECT, LONGEST_SIDE, MAX_VIEWS, N_TEST, N_TRAIN, scene_rig

    n_train = N_TRAIN if n_train is None else whole(n_train, "n_train", 0, MAX_VIEWS)
    n_test = N_TEST if n_test is None else whole(n_test, "n_test", 1, MAX_VIEWS)
    seed = whole(seed, "seed", 0)
    aspect = optional(number, aspect, "aspect", 0.1, 10)  # a width/height ratio
    if len(scene) == 0:
        raise InputError(name or "scene", "has no splats: a rig cannot be fitted to nothing")
    found = source_dataset(name, scene) if rig == "default" else None
    dataset, fitted, how = found if found else (None, scene, "")
    try:
        built = scene_rig(dataset, fitted, rig, n_train=n_train, n_test=n_test, seed=seed,
                          longest_side=longest_side or LONGEST_SIDE, aspect=aspect or ASPECT, up=up)
    except ValueError as err:
        raise InputError(name or "scene", f"cannot build a rig: {err}") from None
    origin = f"rig {built.rig}" + (f" ({how})" if how else "") + f", {split} views"
    return origin, {"test": built.test, "train": built.train, "all": built.all}[split]


def cameras(scene, rig: str | None = "default", *, cameras=None, split: str | None = None, **options) -> list:
    """The cameras ``harness render SCENE --rig RIG`` renders (:class:`harness.core.cameras.Camera`,
    OpenCV axes): a synthetic rig fitted to the scene (``default``: its embedded cameras, else its
    dataset's rig, else ``auto``), or a camera file's (``cameras=``). ``scene``: a scene, a path or
    a name; ``options``: ``longest_side``, ``n_train``, ``n_test``, ``seed``, ``aspect``, ``up``."""
    from harness.api.scenes import _scene

    name = None if hasattr(scene, "meta") else str(scene)
    return views(_scene(scene), cameras=cameras, rig=None if cameras else rig, split=split, name=name,
                 **options)[1]
