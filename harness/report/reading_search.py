"""The pre-registered greedy selection of a pruner's parameters: BetaDescPrune's reading (rule:
``ctc_configs/reading.yaml``) and the virtual rig's geometry (``ctc_configs/virtualrig.yaml``).

Pure functions over a run config's raw mapping and the tidy results of its runs; the driver that
runs the stages is ``harness bench reading`` (:mod:`harness.benchmarks.reading`; named
tools/reading_search.py when the rule was pre-registered in commit 70c2edb).

* :func:`search_space` reads the rule's start (the ``params`` of the first sweep entry of
  ``method``) and the axes (one per sweep entry, in file order; the start's value first).
* :func:`evaluate_axis` computes, for one axis on the current incumbent, D (vs the reference) with
  its CI for every value on every selection scene, the candidate (highest mean D over the scenes
  among the non-incumbent values) and the paired candidate − incumbent difference with its CI; the
  candidate is adopted iff that mean exceeds the CI half-width on every selection scene (with
  ``ignore_unchanged``: every scene where the candidate changes anything — an exactly zero difference
  with a zero-width CI on every view means the axis does not apply there — and on at least one).
* The searched pruner (``method``), the reference side and the variant-label prefix are fields of the
  :class:`SearchSpace` (defaults: betadesc, random, ``lit``).
* :func:`selection_markdown` and :func:`confirmation_markdown` write the report tables.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any, Mapping

import pandas as pd

from harness.report.paired import Paired, compare

METHOD = "betadesc"


@dataclass(frozen=True)
class Axis:
    name: str
    values: tuple  # the start's value first


@dataclass(frozen=True)
class SearchSpace:
    start: dict[str, Any]  # the start's params as written (e.g. {"reading": "paper-literal"})
    axes: tuple[Axis, ...]
    scenes: tuple[str, ...]
    ratio: float
    reference: dict[str, Any]  # {"method": "random"}
    method: str = METHOD
    prefix: str = "lit"


@dataclass
class AxisResult:
    axis: str
    incumbent: dict[str, Any]  # full params (start + adopted values) before this axis
    d: dict[tuple[Any, str], Paired] = field(default_factory=dict)  # (value, scene) -> D vs reference
    candidate: Any = None
    delta: dict[str, Paired] = field(default_factory=dict)  # scene -> candidate − incumbent
    adopted: bool = False

    @property
    def chosen(self):
        return self.candidate if self.adopted else self.incumbent[self.axis]


def resolved(params: Mapping[str, Any], method: str = METHOD) -> dict[str, Any]:
    """The full, validated parameter dict of ``method`` for ``params`` (bundle applied)."""
    from methods.registry import get_pruner

    return get_pruner(method).parse_params(dict(params)).to_dict()


def search_space(raw: Mapping[str, Any], method: str = METHOD, reference: Mapping[str, Any] | None = None,
                 prefix: str = "lit") -> SearchSpace:
    """The start and axes encoded in a selection config (see the module docstring)."""
    entries = [m for m in raw["methods"] if isinstance(m, Mapping) and m.get("name") == method and m.get("sweep")]
    if not entries:
        raise ValueError(f"no sweep entries of {method} in the config")
    start = dict(entries[0].get("params") or {})
    base = resolved(start, method)
    axes = []
    for m in entries:
        if dict(m.get("params") or {}) != start or len(m["sweep"]) != 1:
            raise ValueError("every axis entry must sweep one parameter on the same start params")
        (name, vals), = m["sweep"].items()
        axes.append(Axis(name, tuple([base[name], *vals])))
    scenes = tuple(s["name"] if isinstance(s, Mapping) else s for s in raw["scenes"])
    ratios = raw.get("ratios") or [0.3]
    return SearchSpace(start, tuple(axes), scenes, float(ratios[0]), dict(reference or {"method": "random"}),
                       method, prefix)


def with_value(incumbent: Mapping[str, Any], axis: str, value) -> dict[str, Any]:
    return {**incumbent, axis: value}


def overrides(space: SearchSpace, params: Mapping[str, Any]) -> dict[str, Any]:
    """``params`` as the start plus the axis values that differ from the start's (config form)."""
    base = resolved(space.start, space.method)
    return {**space.start, **{a.name: params[a.name] for a in space.axes if params[a.name] != base[a.name]}}


def label(space: SearchSpace, params: Mapping[str, Any]) -> str:
    """A short, stable variant name: the prefix (``lit``) + the axis values that differ from the start."""
    extra = overrides(space, params)
    diff = [f"{a.name}={_fmt(extra[a.name])}" for a in space.axes if a.name in extra]
    return space.prefix + ("+" + "+".join(diff) if diff else "")


def _fmt(v) -> str:
    return format(v, "g") if isinstance(v, float) else str(v)


def _match(params: Mapping[str, Any], space: SearchSpace) -> dict[str, Any]:
    """The row-matching subset of full params: every value but the ``reading`` label (two rows with the
    same values and different bundle names are the same reading)."""
    return {k: v for k, v in params.items() if k != "reading"}


def missing(df: pd.DataFrame, space: SearchSpace, wanted: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The wanted full param dicts that have no ok rows on some selection scene."""
    rows = df[(df["status"] == "ok") & (df["method"] == space.method) & ((df["ratio"] - space.ratio).abs() < 1e-9)]
    have = {(r.scene, json.dumps(_match(json.loads(r.params), space), sort_keys=True))
            for r in rows[["scene", "params"]].drop_duplicates().itertuples()}
    out = []
    for p in wanted:
        key = json.dumps(_match(p, space), sort_keys=True)
        if any((s, key) not in have for s in space.scenes) and p not in out:
            out.append(p)
    return out


def evaluate_axis(df: pd.DataFrame, space: SearchSpace, axis: Axis, incumbent: dict[str, Any], *,
                  ignore_unchanged: bool = False) -> AxisResult:
    """One step of the rule (module docstring); ``incumbent`` holds full params."""
    res = AxisResult(axis.name, dict(incumbent))
    side = {v: {"method": space.method, "params": _match(with_value(incumbent, axis.name, v), space)} for v in axis.values}
    for v in axis.values:
        for s in space.scenes:
            res.d[(v, s)] = compare(df, scene=s, ratio=space.ratio, candidate=side[v], reference=space.reference)
    others = [v for v in axis.values if v != incumbent[axis.name]]
    mean_d = {v: sum(res.d[(v, s)].mean for s in space.scenes) / len(space.scenes) for v in others}
    res.candidate = max(others, key=lambda v: (mean_d[v], -others.index(v)))
    for s in space.scenes:
        res.delta[s] = compare(df, scene=s, ratio=space.ratio, candidate=side[res.candidate],
                               reference=side[incumbent[axis.name]])
    judged = [p for p in res.delta.values()
              if not (ignore_unchanged and p.n > 0 and p.mean == 0 and p.half_width == 0)]
    res.adopted = bool(judged) and all(p.n > 0 and p.mean > p.half_width for p in judged)
    return res


def selection_markdown(space: SearchSpace, steps: list[AxisResult], selected: Mapping[str, Any],
                       criterion: str | None = None) -> str:
    ref = space.reference.get("method", "the reference")
    lines = [criterion or (f"Criterion: D = mean paired per-view PSNR difference vs {ref} at {space.ratio:.0%} "
             "pruning (dB), with its 95 % percentile-bootstrap CI (10,000 resamples of the views, seed 0); "
             "`n` views used (`x` excluded at >= 100 dB)."), ""]
    for i, st in enumerate(steps, 1):
        lines += [f"### Axis {i}: `{st.axis}` (incumbent `{_fmt(st.incumbent[st.axis])}`)", "",
                  "| value | " + " | ".join(f"D {s} [CI] (n/x)" for s in space.scenes) + " |",
                  "|---|" + "---|" * len(space.scenes)]
        values = list(dict.fromkeys(v for v, _ in st.d))
        for v in values:
            mark = " (incumbent)" if v == st.incumbent[st.axis] else (" (candidate)" if v == st.candidate else "")
            cells = [f"{st.d[(v, s)].text()} ({st.d[(v, s)].n}/{st.d[(v, s)].n_excluded})" for s in space.scenes]
            lines.append(f"| `{_fmt(v)}`{mark} | " + " | ".join(cells) + " |")
        deltas = "; ".join(f"{s}: {p.text()} (half-width {p.half_width:.2f})" for s, p in st.delta.items())
        verdict = "**adopted**" if st.adopted else "not adopted (incumbent kept)"
        lines += ["", f"Candidate `{_fmt(st.candidate)}` − incumbent: {deltas} → {verdict}.", ""]
    lines += ["### Selected " + ("reading" if space.method == METHOD else "parameters"), "",
              "| axis | value |", "|---|---|"]
    lines += [f"| `{a.name}` | `{_fmt(selected[a.name])}` |" for a in space.axes]
    return "\n".join(lines) + "\n"


def confirmation_markdown(df: pd.DataFrame, scenes: list[str], ratios: list[float],
                          sides: list[tuple[str, dict[str, Any]]], reference: Mapping[str, Any]) -> str:
    """Per scene and ratio, D vs ``reference`` with CI for each named side (``{method, variant}``)."""
    lines = ["| scene | ratio | " + " | ".join(name for name, _ in sides) + " |",
             "|---|---|" + "---|" * len(sides)]
    for s in scenes:
        for r in ratios:
            cells = []
            for _, side in sides:
                try:
                    p = compare(df, scene=s, ratio=r, candidate=side, reference=reference)
                    cells.append(f"{p.text()} ({p.n}/{p.n_excluded})")
                except KeyError:
                    cells.append("n/a")
            lines.append(f"| {s} | {r:.0%} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
