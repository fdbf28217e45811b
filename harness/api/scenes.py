"""Scenes from Python: :func:`load`, :func:`save`, :func:`info`, :func:`score`, :func:`prune`, :func:`methods`.

The commands ``harness prune``, ``convert``, ``info`` and ``methods`` are these functions plus their
printing, so a scene pruned here is the file ``harness prune`` writes, byte for byte. Errors are
:class:`harness.HarnessError` naming the keyword argument (``ratio: must be a number in [0, 1]``);
the commands rename them to their flags (:func:`harness.core.errors.naming`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from harness.core.errors import InputError

if TYPE_CHECKING:  # numpy and the scene model are imported where they are used
    import numpy as np

    from harness.core.scene import GaussianScene

DEFAULT_METHOD = "betadesc"


def load(path_or_name, *, lod: int | str | None = None, drop_nonfinite: bool = False) -> GaussianScene:
    """The scene in a file (.ply, .compressed.ply, .spz, .ksplat, .splat, SOG) or a named dataset
    (``"bonsai-7k"``), validated: a :class:`harness.core.scene.GaussianScene`. ``lod``: a SOG level
    or ``"all"``; ``drop_nonfinite`` drops NaN/inf splats instead of refusing them."""
    from harness.io.scenes import load_scene

    return load_scene(path_or_name, lod=lod, drop_nonfinite=drop_nonfinite)


def _scene(scene, seconds: dict | None = None):
    """``scene`` validated (:func:`harness.core.validate.validate`: a scene changed in memory is held
    to the readers' rules), or the scene loaded from a path or name (timed as ``seconds["read"]``)."""
    from harness.core.scene import GaussianScene
    from harness.core.validate import validate

    if isinstance(scene, GaussianScene):
        return validate(scene, "scene", hint="drop those rows (scene.subset) or fix them")[0]
    t0 = time.perf_counter()
    loaded = load(_scene_argument(scene))
    if seconds is not None:
        seconds["read"] = time.perf_counter() - t0
    return loaded


def _scene_argument(scene):
    if not isinstance(scene, (str, Path)):
        raise InputError("scene", f"expected a scene, a path or a scene name, got {type(scene).__name__}")
    return scene


def info(scene, *, lod: int | str | None = None, drop_nonfinite: bool = False) -> dict:
    """What ``harness info --json`` prints: splat count, SH degree, bounding box, opacity and scale
    statistics, memory (and, for a file, its format and size on disk) and ``dropped_nonfinite``."""
    from harness.core.scene import GaussianScene
    from harness.io.scenes import describe_scene, read_scene

    if isinstance(scene, GaussianScene):
        from harness.core.validate import validate

        checked, dropped = validate(scene, "scene", drop_nonfinite=drop_nonfinite,
                                    hint="pass drop_nonfinite=True to drop them")
        return {**describe_scene(checked, fmt=scene.meta.format or None), "dropped_nonfinite": dropped}
    result = read_scene(_scene_argument(scene), lod=lod, drop_nonfinite=drop_nonfinite)
    described = describe_scene(result.scene, result.path, fmt=result.format, lod=result.lod,
                               format_name=result.format_name)
    return {**described, "dropped_nonfinite": result.dropped_nonfinite}


def check_outputs(outputs: list[Path], inputs: list[Path]) -> None:
    """InputError naming the first output that cannot be written, before any work: its folder must
    exist and be writable (probed), the name must not be a folder or a special file, and no output
    may be an input (or lie inside an input folder; a SOG ``meta.json`` input counts with the
    textures it names). Stale temporary files of an earlier killed write in that folder are swept
    first."""
    from harness.io.files import probe_writable, sweep_stale_temps
    from harness.io.scenes import scene_files

    inputs = [f for src in inputs for f in ([src] if src.is_dir() else scene_files(src))]

    for path in outputs:
        if not path.parent.is_dir():
            raise InputError(path, "output folder does not exist")
        if path.is_dir():
            raise InputError(path, "is a folder; give a file name")
        if path.exists() and not path.is_file():
            raise InputError(path, "exists and is not a regular file")
        probe_writable(path.parent, path)  # read-only, /proc ...: refused before any work
        sweep_stale_temps(path.parent)
        for src in inputs:
            if path.resolve() == src.resolve() or (src.is_dir() and src.resolve() in path.resolve().parents):
                raise InputError(path, f"would overwrite the input {src}; choose another output")


def save(scene, path, *, spz_version: int | None = None) -> Path:
    """Write ``scene`` (a scene, or a path or name to read it from) atomically in the format
    ``path``'s name asks for, as ``harness convert`` (``.ply`` lossless, keeping extra properties
    and header comments; ``.compressed.ply``, ``.splat``, ``.spz`` lossy; ``spz_version`` 2, 3 or
    4); ``.sog`` or ``meta.json`` for PlayCanvas SOG). The file the scene was read from is never
    replaced. Returns the path."""
    from harness.core.scene import GaussianScene
    from harness.io.datasets import resolve_scene
    from harness.io.scenes import write_scene
    from harness.io.writers import writer_for

    out = Path(path)
    files = writer_for(out).files(out)  # the format from the name, refused before anything else
    if isinstance(scene, GaussianScene):
        inputs = [Path(scene.meta.source)] if scene.meta.source else []
    else:
        inputs = [resolve_scene(_scene_argument(scene))]
    check_outputs(files, inputs)
    return write_scene(_scene(scene), out, spz_version=spz_version)


def methods() -> list[dict]:
    """Every registered pruner: name, label, group, needs, ablation cell, summary and parameters
    (type, default, documentation), as ``harness methods --json`` prints them."""
    from methods import list_pruners

    return [{"name": s.name, "label": s.label, "group": s.group, "needs": sorted(s.needs),
             "ablation": None if s.ablation is None else {"descriptors": s.ablation.descriptors,
                                                          "beta": s.ablation.beta},
             "summary": s.summary,
             "params": {p.name: {"type": p.describe(), "default": p.default, "doc": p.doc,
                                 **({"reading": p.reading} if p.reading else {})}
                        for p in s.params.specs()}}
            for s in list_pruners()]


def pruner(method: str, params: dict, *, announce_advice: bool = True):
    """(the pruner's spec, its resolved :class:`harness.core.params.Params`); errors name
    ``method`` or the parameter; the parameters' advisories are printed once (``announce_advice``)."""
    from harness.core.advice import announce
    from harness.core.params import ParamError
    from methods import get_pruner

    try:
        spec = get_pruner(method)
    except KeyError as err:
        raise InputError("method", str(err.args[0])) from None
    try:
        resolved = spec.params.parse(params)
    except ParamError as err:
        raise InputError(err.key or "params", f"method {spec.name!r}: {err.problem}") from None
    if announce_advice:
        announce(f"method {spec.name!r}", resolved)
    return spec, resolved


def _cameras(spec, params, cameras):
    """The training views handed to the pruner (a camera file is read), or None."""
    if cameras is None:
        if "cameras" in spec.needs:
            raise InputError("cameras", f"{spec.name!r} needs training cameras; none were given")
        return None
    if not spec.wants_cameras(params):
        hint = " (its view-aware evidence needs view_weight > 0)" if "view_weight" in params.names() else ""
        raise InputError("cameras", f"{spec.name!r} does not use cameras with these parameters{hint}")
    if isinstance(cameras, (str, Path)):
        from harness.io.cameras import load_cameras

        return load_cameras(cameras)
    from harness.core.cameras import Camera

    cameras = [cameras] if isinstance(cameras, Camera) else list(cameras)
    if not cameras or not all(isinstance(c, Camera) for c in cameras):
        raise InputError("cameras", "expected a camera file or a non-empty list of harness.core.cameras.Camera")
    return cameras


def _ratio(ratio, keep) -> float:
    """The canonical removal ratio from exactly one of ``ratio`` and ``keep`` (:mod:`harness.core.ratios`)."""
    from harness.core import ratios

    if (ratio is None) == (keep is None):
        raise InputError("ratio", "give exactly one of ratio (the fraction removed) and keep (the fraction kept)")
    from harness.core.arguments import number

    value, name = (ratio, "ratio") if ratio is not None else (keep, "keep")
    value = number(value, name, 0, 1)  # True is not a ratio
    return ratios.canonical(value) if name == "ratio" else ratios.from_keep(value)


def _score(spec, params, scene, cameras, seed: int, device: str, seconds: dict):
    from harness.core.timing import record_stages
    from methods import PruneContext

    t0 = time.perf_counter()
    with record_stages() as stages:
        try:
            scores = spec.score(scene, PruneContext(params=params, seed=seed, cameras=cameras, device=device))
        except ValueError as err:  # a value the method rejects only once it sees the scene
            raise InputError("method", f"{spec.name}: {err}") from None
    seconds["score"] = time.perf_counter() - t0
    seconds.update({f"score.{k}": v for k, v in stages.items()})
    return scores


def score(scene, method: str = DEFAULT_METHOD, *, cameras=None, seed: int = 0, device: str = "cpu", **params):
    """Every splat's score under ``method`` (float64 (N,), higher = keep). ``scene``: a scene, a
    path or a name; ``cameras``: a camera file or a list of :class:`harness.core.cameras.Camera`
    (pruners that need training views); ``params``: the pruner's parameters (``harness methods``)."""
    from harness.core.arguments import whole
    from harness.core.devices import check_device

    spec, resolved = pruner(method, params)
    seed = whole(seed, "seed", 0)
    check_device(device, "device")
    cams = _cameras(spec, resolved, cameras)
    return _score(spec, resolved, _scene(scene), cams, seed, device, {})


@dataclass(frozen=True)
class Pruned:
    """A pruned scene: ``scene`` the kept splats (in input order), ``mask`` bool (N,) with True =
    kept, ``scores`` float64 (N,) (None when nothing was removed and so nothing scored), ``tau``
    the score at the cut (the largest removed score; −inf when nothing was removed), ``removed``
    the count removed, ``seconds`` per stage (``read`` when a path was given, ``score``,
    ``score.<stage>``, ``select``)."""

    scene: GaussianScene
    mask: np.ndarray
    scores: np.ndarray | None
    tau: float
    removed: int
    method: str
    params: dict
    seconds: dict = field(default_factory=dict)

    @property
    def kept(self) -> int:
        return len(self.scene)


def prune(scene, ratio: float | None = None, *, keep: float | None = None, method: str = DEFAULT_METHOD,
          cameras=None, seed: int = 0, device: str = "cpu", **params) -> Pruned:
    """Remove exactly ``round(ratio·N)`` splats (``keep=K`` is ``ratio = 1 − K``): the lowest scores
    under ``method``, ties by index (:mod:`methods.targeting`). Everything is checked before the
    scene is read or scored; ``ratio=0`` scores nothing. See :func:`score` for the arguments."""
    import numpy as np

    from harness.core.arguments import whole
    from harness.core.devices import check_device
    from methods import select_by_ratio

    spec, resolved = pruner(method, params)
    cut = _ratio(ratio, keep)
    seed = whole(seed, "seed", 0)
    check_device(device, "device")
    cams = _cameras(spec, resolved, cameras)
    seconds: dict[str, float] = {}
    scene = _scene(scene, seconds)
    scores = _score(spec, resolved, scene, cams, seed, device, seconds) if cut > 0 else None
    t0 = time.perf_counter()
    selection = select_by_ratio(scores if scores is not None else np.zeros(len(scene)), cut)
    seconds["select"] = time.perf_counter() - t0
    return Pruned(scene=scene.subset(selection.keep), mask=selection.keep, scores=scores, tau=selection.tau,
                  removed=selection.removed, method=spec.name, params=resolved.to_dict(), seconds=seconds)
