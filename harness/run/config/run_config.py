"""Run configuration for ``harness run CONFIG.yaml``: validation and sweep expansion.

A config is a YAML mapping of sections (:data:`SECTIONS`, plus the top level's own keys), each a
dataclass of typed ``config_param(...)`` fields (:mod:`harness.run.config.sections`: one default, range,
doc and what the value changes each); the reference of every key, ``docs/config.md``, is generated
from those declarations (:mod:`harness.run.config.reference`, ``harness config schema``).
``extends: default.yaml`` makes a config another one with its own keys over it (mappings merge key
by key, lists and values replace: :mod:`harness.run.config.files`); ``harness config show CONFIG``
prints the resolved config with the file and line of every value.

Every problem is an :class:`InputError` naming the key path (``methods[2].sweep.voxel``) and what
is wrong. Variant names are stable: ``<variant or 'default'>`` for plain entries, and
``k1=v1,k2=v2`` (keys in the order written) for sweep combinations, prefixed by ``variant`` when
given.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from harness.core import ratios
from harness.core.errors import InputError
from harness.core.suggest import unknown
from harness.report.plots import PLOTS
from harness.report.tables import TABLES
from harness.run.config.checks import expand_env
from harness.run.config.checks import mapping as _mapping
from harness.run.config.checks import string as _str
from harness.run.config.executor import ExecutorSpec, parse_executor
from harness.run.config.schema import read_section
from harness.run.config.sections import (  # noqa: F401  (the sections are imported from here)
    KINDS,
    CameraSpec,
    MethodEntry,
    MethodVariant,
    Protocol,
    SceneSpec,
    Settings,
)
from harness.run.config.sections import pruner as _pruner
from harness.run.config.views import protocols as _protocols
from harness.views.protocols import PRIMARY, protocol

SECTIONS = ("protocol", "scenes", "methods", "protocols", "executor")


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
    #: held-out view protocols (harness.views.protocols.Protocol); the first is the primary one
    protocols: tuple = field(default_factory=lambda: (protocol(PRIMARY),))
    executor: ExecutorSpec = field(default_factory=ExecutorSpec)


def merge_ratios(ratio_list, keep) -> tuple[float, ...]:
    """Sorted union of pruning ratios and the ratios of keep fractions (:func:`harness.core.ratios.merge`)."""
    return ratios.merge(ratio_list, keep)


# --------------------------------------------------------------------------- reading
def _protocol(d, src) -> Protocol:
    return Protocol(**read_section(Protocol, _mapping(d, "protocol", src), "protocol", src))


def _scene(d, i, protocol: Protocol, src) -> SceneSpec:
    where = f"scenes[{i}]"
    d = _mapping({"name": d} if isinstance(d, str) else d, where, src)
    if "name" not in d:
        raise InputError(src, f"{where}.name: required")
    name = _str(d["name"], f"{where}.name", src)
    for a, b in (("source", "frames"), ("rig", "cameras")):
        if a in d and b in d:
            raise InputError(src, f"{where}: give either `{a}` or `{b}`, not both")
    kw = read_section(SceneSpec, d, where, src, extra=("name", "label"),
                      defaults={"n_train": protocol.n_train, "n_test": protocol.n_test})
    label = _str(d.get("label", name), f"{where}.label", src)
    if "sequence" in d:
        return _sequence_scene(d, where, name, label, kw, src)
    stray = [k for k in ("test", "test_every", "width", "height") if k in d]
    if stray:
        raise InputError(src, f"{where}: {', '.join(stray)} go with `sequence` (for `cameras`, inside it)")
    if "frames" not in d and kw["source"] is None:
        kw["source"] = expand_env(name)
    return SceneSpec(name=name, label=label, **kw)


def _sequence_scene(d, where, name, label, kw, src) -> SceneSpec:
    """A scene given as an MPEG content folder (``sequence: DIR``): its own frames and cameras."""
    clash = [k for k in ("source", "frames", "cameras", "rig", "lod", "capture") if k in d]
    if clash:
        raise InputError(src, f"{where}: `sequence` brings its own frames and cameras; drop {', '.join(clash)}")
    if (kw["width"] is None) != (kw["height"] is None):
        raise InputError(src, f"{where}: give both width and height, or neither")
    keep = ("kind", "sequence", "test", "test_every", "width", "height", "suites", "optional")
    return SceneSpec(name=name, label=label, **{k: kw[k] for k in keep})


def _fmt(v) -> str:
    return format(v, "g") if isinstance(v, float) else str(v)


def _entry_ratios(e: dict, default_ratios, where: str, src) -> tuple[float, ...]:
    """An entry's ratios: its ``ratios``/``keep`` merged, else the top level's (never none)."""
    if e["ratios"] is not None or e["keep"] is not None:
        out = merge_ratios(e["ratios"] or (), e["keep"] or ())
    else:
        out = default_ratios
    if not out:
        raise InputError(src, f"{where}: no pruning ratios (set `ratios`/`keep` here or at the top level)")
    return out


def _entry_names(names, known, key: str, what: str, where: str, src) -> tuple[str, ...] | None:
    """An entry's restriction (``scenes``, ``protocols``) to some of the config's ``known`` names;
    None: all of them."""
    if names is None:
        return None
    if not names:
        raise InputError(src, f"{where}.{key}: expected a non-empty list of {what} names")
    for j, n in enumerate(names):
        if n not in known:
            raise InputError(src, f"{where}.{key}[{j}]: {unknown(f'{what} of this config', n, sorted(known))}")
    return tuple(names)


def _check_sweep(sweep: dict, params: dict, where: str, src) -> None:
    for k, vals in sweep.items():
        if not isinstance(vals, list) or not vals:
            raise InputError(src, f"{where}.sweep.{k}: expected a non-empty list of values")
        if k in params:
            raise InputError(src, f"{where}.sweep.{k}: also set in params; give it in one place")


def _variants(spec, e: dict, where: str, src):
    """(variant name, resolved parameters) of every combination of the entry's sweep (one without)."""
    from harness.core.advice import announce
    from harness.core.params import ParamError

    params, sweep = e["params"] or {}, e["sweep"] or {}
    keys = list(sweep)
    for combo in itertools.product(*(sweep[k] for k in keys)) if keys else [()]:
        label = ",".join(f"{k}={_fmt(v)}" for k, v in zip(keys, combo))
        try:
            resolved = spec.parse_params({**params, **dict(zip(keys, combo))})
        except ParamError as err:
            section = "sweep" if err.key in sweep else "params"
            key = f".{section}.{err.key}" if err.key is not None else f".{section}"
            raise InputError(src, f"{where}{key}: method {e['name']!r}: {err.problem}") from None
        variant = ":".join(x for x in (e["variant"], label) if x) or "default"
        announce(f"{src}: {where} ({e['name']}, variant {variant})", resolved)
        yield variant, resolved


def _method(d, i, default_ratios, scene_names, src, protocol_names=()) -> list[MethodVariant]:
    """Expand one methods[] entry into its variants, each with its parameters resolved and checked
    (through the pruner's :class:`Params`) here, once."""
    where = f"methods[{i}]"
    d = _mapping({"name": d} if isinstance(d, str) else d, where, src)
    e = read_section(MethodEntry, d, where, src)
    if e["name"] is None:
        _str(None, f"{where}.name", src)  # required: "expected a non-empty string"
    _check_sweep(e["sweep"] or {}, e["params"] or {}, where, src)
    rs = _entry_ratios(e, default_ratios, where, src)
    scenes = _entry_names(e["scenes"], scene_names, "scenes", "scene", where, src)
    protocols = _entry_names(e["protocols"], protocol_names, "protocols", "protocol", where, src)
    spec = _pruner(e["name"], f"{where}.name", src)
    return [MethodVariant(method=e["name"], variant=v, params=p, ratios=rs, scenes=scenes, protocols=protocols)
            for v, p in _variants(spec, e, where, src)]


def _scenes(d, protocol: Protocol, src) -> list[SceneSpec]:
    raw = d.get("scenes")
    if not isinstance(raw, list) or not raw:
        raise InputError(src, "scenes: expected a non-empty list of scenes")
    scenes = [_scene(s, i, protocol, src) for i, s in enumerate(raw)]
    seen: set[str] = set()
    for i, s in enumerate(scenes):
        if s.name in seen:
            raise InputError(src, f"scenes[{i}].name: duplicate scene name {s.name!r}")
        seen.add(s.name)
    return scenes


def _methods(d, default_ratios, scene_names, src, protocol_names=()) -> list[MethodVariant]:
    raw = d.get("methods")
    if not isinstance(raw, list) or not raw:
        raise InputError(src, "methods: expected a non-empty list of methods")
    methods: list[MethodVariant] = []
    keys: dict[str, int] = {}
    for i, m in enumerate(raw):
        for v in _method(m, i, default_ratios, scene_names, src, protocol_names):
            if v.key in keys:
                raise InputError(src, f"methods[{i}]: variant {v.key} already defined by methods[{keys[v.key]}]; "
                                      "give one of them a distinct `variant`")
            keys[v.key] = i
            methods.append(v)
    return methods


def _check_names(scenes, methods, src) -> None:
    """Every name the run prints or turns into a file name, before any work (:mod:`harness.core.names`:
    length, control characters, two names that would share a file on a case-insensitive file system)."""
    from harness.core.names import collisions, name_problem

    named = [(f"scenes[{i}].{k}", getattr(s, k)) for i, s in enumerate(scenes) for k in ("name", "label")]
    named += [(f"methods: {v.method} variant", v.variant) for v in methods]
    for where, name in named:
        if (why := name_problem(name)) is not None:
            raise InputError(src, f"{where}: {why}")
    groups = [[(f"scenes[{i}].name {s.name!r}", s.name) for i, s in enumerate(scenes)]]
    groups += [[(f"{v.method} variant {v.variant!r}", v.variant) for v in methods if v.method == m]
               for m in dict.fromkeys(v.method for v in methods)]
    for group in groups:
        if (clash := collisions(group)) is not None:
            raise InputError(src, f"{clash[0]} and {clash[1]} differ only in case: on a case-insensitive file "
                                  "system their files would be one")


def parse_config(data: Any, source: str = "<config>") -> RunConfig:
    """Validate a parsed YAML document (its ``extends`` resolved) and expand method sweeps."""
    from harness.run.config.files import resolve

    src = source
    data, _ = resolve(data, source)
    d = _mapping(data, "top level", src)
    top = read_section(Settings, d, "", src, extra=SECTIONS)
    protocol = _protocol(d.get("protocol"), src)
    scenes = _scenes(d, protocol, src)
    default_ratios = merge_ratios(top["ratios"], top["keep"])
    protocols = _protocols(d.get("protocols", ["rig"]), src)
    methods = _methods(d, default_ratios, {s.name for s in scenes}, src, [p.name for p in protocols])
    _check_names(scenes, methods, src)
    name = top["name"] if top["name"] is not None else _str(Path(source).stem, "name", src)
    return RunConfig(
        name=name, output=top["output"] or f"runs/{name}", workers=top["workers"], protocol=protocol,
        scenes=scenes, methods=methods, tables=top["tables"], plots=top["plots"], source_path=str(source), raw=d,
        anchor=top["anchor"], protocols=protocols,
        executor=parse_executor(d.get("executor"), src),
    )


def load_config(path: str | Path) -> RunConfig:
    """Read and validate a YAML run config; any problem is an InputError naming the file and key.

    Read through :func:`harness.io.safe_yaml.load_yaml`: a regular file of at most 1 MiB of UTF-8,
    duplicate keys refused, aliases bounded (no "billion laughs")."""
    from harness.io.safe_yaml import load_yaml

    path = Path(path)
    if not path.exists():
        raise InputError(path, "cannot read config: no such file")
    return parse_config(load_yaml(path), str(path))
