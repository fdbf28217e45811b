"""Run configuration for ``harness run CONFIG.yaml``: schema, validation and sweep expansion.

A config is a YAML mapping::

    name: default                 # run name (default: the file's stem)
    output: runs/default          # results directory (relative to the working directory)
    workers: 2                    # local process pool size (--workers overrides)
    executor: local               # or ray (--executor / --address override); as a mapping:
                                  # {name: ray, address: auto, cpus_per_task: 2, gpus_per_task: 0.5,
                                  #  max_retries: 2}; address: absent = a local Ray cluster of
                                  # `workers` workers, auto, HOST:PORT or ray://HOST:10001
    protocol:                     # how every scene is evaluated
      longest_side: 512           # render resolution (px, longest image side; default 1024)
      aspect: 1.3333              # width / height of rig views (default: the rig's own — a named
                                  # dataset's table entry, else 4/3)
      background: [0, 0, 0]
      renderer: gl                # gl | reference
      device: cpu                 # torch device for metrics / camera-aware pruners
      metrics: [psnr, ssim, lpips]
      seed: 0
      n_train: 48                 # rig views handed to camera-aware pruners (default 48)
      n_test: 8                   # held-out rig views that are measured (default 8)
    anchor: lightgs               # BD-rate / BD-PSNR anchor of the bd table (default lightgs)
    ratios: [0.1, 0.2, 0.3]       # default pruning ratios of every method
    keep: [0.7, 0.5, 0.3]         # default keep fractions (ratio = 1 - keep), merged with ratios
    scenes:
      - name: luigi               # row label; also the dataset name or path when `source` is absent
        source: luigi             # dataset name (harness.io.datasets) or a path; ${VAR:-default} expanded
        frames: "dir/*.ply"       # instead of source: a glob of per-frame files (one sequence)
        sequence: dir             # instead of source/frames/cameras: an MPEG content folder
                                  # (track/ or plys/ per-frame PLYs, COLMAP or header cameras;
                                  # harness.io.sequences), rendered at its native size with all
                                  # its cameras; optional test: [names] / test_every: k,
                                  # width/height for header cameras without a size
        kind: object-centric      # or forward-facing (picks the `forward` rig for rig: default)
        rig: default              # `default` (a named dataset's own rig, else auto), or orbit, room,
                                  # forward, auto (harness.views.rigs; same meaning as `harness render --rig`)
        cameras: {path: cams.json, test: [v08, v10], test_every: 8}   # instead of a rig
        capture: {cameras: cams.json, images: photos/, split: split.json, transform: t.json}
                                  # the real capture (harness.io.capture): views and photos of the
                                  # `real` protocol; named scenes carry theirs (bonsai-7k, bonsai-7k-mini),
                                  # `capture: false` drops it; split | test: [names] | test_every: k
        lod: 0                    # SOG level of detail
        n_test: 3                 # per-scene override of protocol.n_test / n_train
        label: "plant"            # display name in tables (default: name)
        suites: [paper-table1]    # free tags
        optional: true            # skip the scene when its files are absent (default false: a scene
                                  # that cannot be found stops the run before any work)
    methods:
      - name: betadesc            # a registered pruner
        variant: default          # row label of this entry (default: "default" or the sweep values)
        params: {gamma: 0.25}
        sweep: {preset: [baseline, flat]}   # cartesian product -> one variant per combination
        ratios: [0.3]             # overrides the default ratios (keep: likewise)
        scenes: [luigi]           # restrict to these scene names
    protocols: [rig, shifted, real]   # held-out view protocols (the first: the primary one);
                                  # {name: real, n_test: 8}: the first 8 captured views by name
    tables: [comparison, ablation, keep, sensitivity, runtime, per_scene]
    plots: [curves, figure1, figure3]

Every problem is an :class:`InputError` naming the key path (``methods[2].sweep.voxel``) and what
is wrong. Variant names are stable: ``<variant or 'default'>`` for plain entries, and
``k1=v1,k2=v2`` (keys in the order written) for sweep combinations, prefixed by ``variant`` when given.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from harness.core import ratios
from harness.core.errors import InputError
from harness.core.suggest import unknown
from harness.core.params import Params
from harness.io.capture import CaptureSpec
from harness.metrics.registry import expand, requestable
from harness.report.plots import PLOTS
from harness.report.tables import TABLES
from harness.run.config_checks import boolean as _bool
from harness.run.config_checks import choice as _choice
from harness.run.config_checks import expand_env
from harness.run.config_checks import fractions as _fractions
from harness.run.config_checks import mapping as _mapping
from harness.run.config_checks import names as _names
from harness.run.config_checks import num as _num
from harness.run.config_checks import only as _only
from harness.run.config_checks import string as _str
from harness.run.config_views import capture as _capture
from harness.run.config_views import protocols as _protocols
from harness.run.executor_spec import ExecutorSpec, parse_executor
from harness.views import rigs
from renderers import RENDERERS

KINDS = ("forward-facing", "object-centric")

@dataclass(frozen=True)
class Protocol:
    longest_side: int = rigs.LONGEST_SIDE
    aspect: float | None = None  # None: the rig's own (a named dataset's table entry, else 4/3)
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    renderer: str = "gl"
    device: str = "cpu"
    metrics: tuple[str, ...] = ("psnr", "ssim", "lpips")
    seed: int = 0
    n_train: int = rigs.N_TRAIN
    n_test: int = rigs.N_TEST


@dataclass(frozen=True)
class CameraSpec:
    """Cameras from a file; held-out views by name (``test``) or every k-th view (``test_every``)."""

    path: str
    test: tuple[str, ...] = ()
    test_every: int = 0


@dataclass(frozen=True)
class SceneSpec:
    name: str
    label: str
    source: str | None = None
    frames: str | None = None
    kind: str = "object-centric"
    rig: str = "default"
    cameras: CameraSpec | None = None
    lod: int | None = None
    n_train: int = rigs.N_TRAIN
    n_test: int = rigs.N_TEST
    suites: tuple[str, ...] = ()
    #: an MPEG content folder (harness.io.sequences): per-frame PLYs + cameras, native resolution,
    #: every camera measured unless ``test`` / ``test_every`` name the views
    sequence: str | None = None
    test: tuple[str, ...] = ()
    test_every: int = 0
    width: int | None = None    # image size for header camera lines without one (default 1920x1080)
    height: int | None = None
    #: absent files are skipped with a message (MPEG content not everyone has); otherwise a scene
    #: that cannot be found is an error before any work (:func:`harness.run.plan.check_sources`)
    optional: bool = False
    #: the scene's capture (real cameras, split, photos; harness.io.capture) for the `real` protocol;
    #: None: a named scene's own (SCENE_CAPTURES), if any; False: none (`capture: false`)
    capture: CaptureSpec | bool | None = None


@dataclass(frozen=True)
class MethodVariant:
    """One (pruner, resolved parameters) to evaluate at ``ratios`` on ``scenes`` (None = all)."""

    method: str
    variant: str
    params: Params
    ratios: tuple[float, ...]
    scenes: tuple[str, ...] | None = None

    @property
    def key(self) -> str:
        return f"{self.method}[{self.variant}]"


@dataclass
class RunConfig:
    name: str
    output: str
    workers: int
    protocol: Protocol
    scenes: list[SceneSpec]
    methods: list[MethodVariant]
    tables: tuple[str, ...] = TABLES
    plots: tuple[str, ...] = PLOTS
    source_path: str = ""
    raw: dict = field(default_factory=dict)
    anchor: str = "lightgs"  # the BD table's anchor method (harness.report.bd)
    #: held-out view protocols (harness.views.rigs.ViewProtocol); the first is the primary one
    protocols: tuple = (rigs.PROTOCOLS["rig"],)
    executor: ExecutorSpec = field(default_factory=ExecutorSpec)


def merge_ratios(ratio_list, keep) -> tuple[float, ...]:
    """Sorted union of pruning ratios and the ratios of keep fractions (:func:`harness.core.ratios.merge`)."""
    return ratios.merge(ratio_list, keep)


# --------------------------------------------------------------------------- sections
def _protocol(d, src) -> Protocol:
    d = _mapping(d, "protocol", src)
    _only(d, set(Protocol.__dataclass_fields__), "protocol", src)
    p = Protocol()
    kw: dict[str, Any] = {}
    if "longest_side" in d:
        kw["longest_side"] = _num(d["longest_side"], "protocol.longest_side", src, lo=8, hi=8192, integer=True)
    if "aspect" in d:
        kw["aspect"] = float(_num(d["aspect"], "protocol.aspect", src, lo=0.1, hi=10))
    if "background" in d:
        bg = d["background"]
        if not isinstance(bg, list) or len(bg) != 3:
            raise InputError(src, "protocol.background: expected three numbers in [0, 1]")
        kw["background"] = tuple(float(_num(x, f"protocol.background[{i}]", src, lo=0, hi=1)) for i, x in enumerate(bg))
    if "renderer" in d:
        kw["renderer"] = _choice(d["renderer"], RENDERERS.names(), "protocol.renderer", src)
    if "device" in d:
        kw["device"] = _str(d["device"], "protocol.device", src)
    if "metrics" in d:
        if not isinstance(d["metrics"], list) or not d["metrics"]:
            raise InputError(src, "protocol.metrics: expected a non-empty list of metric or metric-set names")
        kw["metrics"] = expand(_names(d["metrics"], requestable(), "protocol.metrics", src, "metric or metric set"))
    if "seed" in d:
        kw["seed"] = _num(d["seed"], "protocol.seed", src, lo=0, integer=True)
    for k in ("n_train", "n_test"):
        if k in d:
            kw[k] = _num(d[k], f"protocol.{k}", src, lo=0 if k == "n_train" else 1, hi=rigs.MAX_VIEWS, integer=True)
    return Protocol(**{**p.__dict__, **kw})


def _cameras(d, where, src) -> CameraSpec:
    d = _mapping(d, where, src)
    _only(d, {"path", "test", "test_every"}, where, src)
    if "path" not in d:
        raise InputError(src, f"{where}.path: required (the cameras file)")
    test = d.get("test", [])
    if not isinstance(test, list) or not all(isinstance(t, str) for t in test):
        raise InputError(src, f"{where}.test: expected a list of view names")
    every = _num(d.get("test_every", 0), f"{where}.test_every", src, lo=0, integer=True)
    if not test and not every:
        raise InputError(src, f"{where}: give the held-out views as `test: [names]` or `test_every: k`")
    return CameraSpec(path=expand_env(_str(d["path"], f"{where}.path", src)), test=tuple(test), test_every=every)


_SCENE_KEYS = {"name", "label", "source", "frames", "kind", "rig", "cameras", "lod", "n_train", "n_test", "suites",
               "sequence", "test", "test_every", "width", "height", "optional", "capture"}

_SEQUENCE_ONLY = ("test", "test_every", "width", "height")


def _scene(d, i, protocol: Protocol, src) -> SceneSpec:
    where = f"scenes[{i}]"
    if isinstance(d, str):
        d = {"name": d}
    d = _mapping(d, where, src)
    _only(d, _SCENE_KEYS, where, src)
    if "name" not in d:
        raise InputError(src, f"{where}.name: required")
    name = _str(d["name"], f"{where}.name", src)
    if "source" in d and "frames" in d:
        raise InputError(src, f"{where}: give either `source` or `frames`, not both")
    if "rig" in d and "cameras" in d:
        raise InputError(src, f"{where}: give either `rig` or `cameras`, not both")
    suites = d.get("suites", [])
    if not isinstance(suites, list) or not all(isinstance(s, str) for s in suites):
        raise InputError(src, f"{where}.suites: expected a list of tags")
    if "sequence" in d:
        return _sequence_scene(d, where, name, suites, src, _bool(d.get("optional", False), f"{where}.optional", src))
    stray = [k for k in _SEQUENCE_ONLY if k in d]
    if stray:
        raise InputError(src, f"{where}: {', '.join(stray)} go with `sequence` (for `cameras`, inside it)")
    lod = d.get("lod")
    return SceneSpec(
        name=name,
        label=_str(d.get("label", name), f"{where}.label", src),
        source=None if "frames" in d else expand_env(_str(d.get("source", name), f"{where}.source", src)),
        frames=expand_env(_str(d["frames"], f"{where}.frames", src)) if "frames" in d else None,
        kind=_choice(d.get("kind", "object-centric"), KINDS, f"{where}.kind", src),
        rig=_choice(d.get("rig", "default"), rigs.RIG_CHOICES, f"{where}.rig", src),
        cameras=_cameras(d["cameras"], f"{where}.cameras", src) if "cameras" in d else None,
        lod=None if lod is None else _num(lod, f"{where}.lod", src, lo=0, integer=True),
        n_train=_num(d.get("n_train", protocol.n_train), f"{where}.n_train", src, lo=0, hi=rigs.MAX_VIEWS, integer=True),
        n_test=_num(d.get("n_test", protocol.n_test), f"{where}.n_test", src, lo=1, hi=rigs.MAX_VIEWS, integer=True),
        suites=tuple(suites),
        optional=_bool(d.get("optional", False), f"{where}.optional", src),
        capture=_capture(d["capture"], f"{where}.capture", src) if "capture" in d else None,
    )


def _sequence_scene(d, where, name, suites, src, optional: bool) -> SceneSpec:
    """A scene given as an MPEG content folder (``sequence: DIR``)."""
    clash = [k for k in ("source", "frames", "cameras", "rig", "lod", "capture") if k in d]
    if clash:
        raise InputError(src, f"{where}: `sequence` brings its own frames and cameras; drop {', '.join(clash)}")
    test = d.get("test", [])
    if not isinstance(test, list) or not all(isinstance(t, str) for t in test):
        raise InputError(src, f"{where}.test: expected a list of view names")
    size = [None if d.get(k) is None else _num(d[k], f"{where}.{k}", src, lo=1, hi=16384, integer=True)
            for k in ("width", "height")]
    if (size[0] is None) != (size[1] is None):
        raise InputError(src, f"{where}: give both width and height, or neither")
    return SceneSpec(
        name=name, label=str(d.get("label", name)), source=None,
        kind=_choice(d.get("kind", "object-centric"), KINDS, f"{where}.kind", src),
        sequence=expand_env(_str(d["sequence"], f"{where}.sequence", src)), test=tuple(test),
        test_every=_num(d.get("test_every", 0), f"{where}.test_every", src, lo=0, integer=True),
        width=size[0], height=size[1], suites=tuple(suites), optional=optional,
    )


def _fmt(v) -> str:
    return format(v, "g") if isinstance(v, float) else str(v)


def _method(d, i, default_ratios, scene_names, src) -> list[MethodVariant]:
    """Expand one methods[] entry into its variants, each with its parameters resolved and checked
    (through the pruner's :class:`Params`) here, once."""
    from harness.core.params import ParamError

    where = f"methods[{i}]"
    if isinstance(d, str):
        d = {"name": d}
    d = _mapping(d, where, src)
    _only(d, {"name", "variant", "params", "sweep", "ratios", "keep", "scenes"}, where, src)
    name = _str(d.get("name"), f"{where}.name", src)
    spec = _pruner(name, f"{where}.name", src)
    params = _mapping(d.get("params"), f"{where}.params", src)
    sweep = _mapping(d.get("sweep"), f"{where}.sweep", src)
    for k, vals in sweep.items():
        if not isinstance(vals, list) or not vals:
            raise InputError(src, f"{where}.sweep.{k}: expected a non-empty list of values")
        if k in params:
            raise InputError(src, f"{where}.sweep.{k}: also set in params; give it in one place")
    if "ratios" in d or "keep" in d:
        ratios = merge_ratios(_fractions(d["ratios"], f"{where}.ratios", src) if "ratios" in d else (),
                              _fractions(d["keep"], f"{where}.keep", src) if "keep" in d else ())
    else:
        ratios = default_ratios
    if not ratios:
        raise InputError(src, f"{where}: no pruning ratios (set `ratios`/`keep` here or at the top level)")
    scenes = None
    if "scenes" in d:
        scenes = d["scenes"]
        if not isinstance(scenes, list) or not scenes:
            raise InputError(src, f"{where}.scenes: expected a non-empty list of scene names")
        for j, s in enumerate(scenes):
            if s not in scene_names:
                raise InputError(src, f"{where}.scenes[{j}]: {unknown('scene of this config', s, sorted(scene_names))}")
        scenes = tuple(scenes)
    base = d.get("variant")
    if base is not None:
        base = _str(base, f"{where}.variant", src)
    out = []
    keys = list(sweep)
    for j, combo in enumerate(itertools.product(*(sweep[k] for k in keys)) if keys else [()]):
        label = ",".join(f"{k}={_fmt(v)}" for k, v in zip(keys, combo))
        variant = ":".join(x for x in (base, label) if x) or "default"
        try:
            resolved = spec.parse_params({**params, **dict(zip(keys, combo))})
        except ParamError as err:
            section = "sweep" if err.key in sweep else "params"
            key = f".{section}.{err.key}" if err.key is not None else f".{section}"
            raise InputError(src, f"{where}{key}: method {name!r}: {err.problem}") from None
        out.append(MethodVariant(method=name, variant=variant, params=resolved, ratios=ratios, scenes=scenes))
    return out


def _anchor(v, src) -> str:
    """The BD anchor: a registered pruner name."""
    name = _str(v, "anchor", src)
    _pruner(name, "anchor", src)
    return name


def _pruner(name: str, where: str, src):
    """The registered pruner ``name``, or an InputError with the known names and the close ones."""
    from methods.registry import get_pruner, list_pruners

    try:
        return get_pruner(name)
    except KeyError:
        raise InputError(src, f"{where}: {unknown('method', name, [p.name for p in list_pruners()])}") from None


def parse_config(data: Any, source: str = "<config>") -> RunConfig:
    """Validate a parsed YAML document and expand method sweeps."""
    src = source
    d = _mapping(data, "top level", src)
    _only(d, {"name", "output", "workers", "protocol", "ratios", "keep", "scenes", "methods", "tables", "plots",
              "anchor", "protocols", "executor"}, "top level", src)
    protocol = _protocol(d.get("protocol"), src)
    scenes_raw = d.get("scenes")
    if not isinstance(scenes_raw, list) or not scenes_raw:
        raise InputError(src, "scenes: expected a non-empty list of scenes")
    scenes = [_scene(s, i, protocol, src) for i, s in enumerate(scenes_raw)]
    seen: set[str] = set()
    for i, s in enumerate(scenes):
        if s.name in seen:
            raise InputError(src, f"scenes[{i}].name: duplicate scene name {s.name!r}")
        seen.add(s.name)
    ratios = merge_ratios(_fractions(d["ratios"], "ratios", src) if "ratios" in d else (),
                          _fractions(d["keep"], "keep", src) if "keep" in d else ())
    methods_raw = d.get("methods")
    if not isinstance(methods_raw, list) or not methods_raw:
        raise InputError(src, "methods: expected a non-empty list of methods")
    methods: list[MethodVariant] = []
    keys: dict[str, int] = {}
    for i, m in enumerate(methods_raw):
        for v in _method(m, i, ratios, seen, src):
            if v.key in keys:
                raise InputError(src, f"methods[{i}]: variant {v.key} already defined by methods[{keys[v.key]}]; "
                                      "give one of them a distinct `variant`")
            keys[v.key] = i
            methods.append(v)
    name = _str(d.get("name", Path(source).stem), "name", src)
    return RunConfig(
        name=name,
        output=expand_env(_str(d.get("output", f"runs/{name}"), "output", src)),
        workers=_num(d.get("workers", 1), "workers", src, lo=1, hi=256, integer=True),
        protocol=protocol,
        scenes=scenes,
        methods=methods,
        tables=_names(d.get("tables", list(TABLES)), TABLES, "tables", src, "table"),
        plots=_names(d.get("plots", list(PLOTS)), PLOTS, "plots", src, "plot"),
        source_path=str(source),
        raw=d,
        anchor=_anchor(d.get("anchor", "lightgs"), src),
        protocols=_protocols(d.get("protocols", ["rig"]), src),
        executor=parse_executor(d.get("executor"), src),
    )


def load_config(path: str | Path) -> RunConfig:
    """Read and validate a YAML run config; any problem is an InputError naming the file and key.

    Read through :func:`harness.io.safe.load_yaml`: a regular file of at most 1 MiB of UTF-8,
    duplicate keys refused, aliases bounded (no "billion laughs")."""
    from harness.io.safe import load_yaml

    path = Path(path)
    if not path.exists():
        raise InputError(path, "cannot read config: no such file")
    return parse_config(load_yaml(path), str(path))
