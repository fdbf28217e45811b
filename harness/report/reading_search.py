"""The pre-registered greedy selection of BetaDescPrune's reading (round one: ``ctc_configs/reading.yaml``,
round two: ``ctc_configs/reading2.yaml``; each rule is in its file's header).

Pure functions over a run config's raw mapping and the tidy results of its runs; the driver that
runs the stages is ``harness bench reading`` (:mod:`harness.benchmarks.reading`; named
tools/reading_search.py when round one was pre-registered in commit 70c2edb).

* :func:`search_space` reads the rule's start (the ``params`` of the first sweep entry of each
  searched method: ``betadesc``, and in round two ``betadesc-nodesc``) and the axes (one per sweep
  entry, in file order). An axis sweeps one parameter (its values, the start's value first) or, in
  round two, several at once: a *joint* axis whose values are the tuples of the sweep's combinations
  (the start's tuple first), named ``a+b+c``.
* :func:`evaluate_axis` computes, for one axis on the current incumbent of its method, D (vs the
  reference) with its 95 % interval for every value on every selection scene, the candidate
  (highest mean D over the scenes among the non-incumbent values) and the paired candidate −
  incumbent difference with its interval; the candidate is adopted iff that mean exceeds the
  interval's half-width on every selection scene. The interval is the round's: the percentile
  bootstrap in round one (its rule), the t interval in round two (:mod:`harness.report.paired`).
* :func:`selection_markdown` and :func:`confirmation_markdown` write the report tables.
"""

from __future__ import annotations

import itertools
import json
from dataclasses import dataclass, field
from typing import Any, Mapping

import pandas as pd

from harness.report.paired import Paired, compare

METHOD = "betadesc"
#: the methods whose sweep entries are axes (round one used only the first)
SEARCHED = ("betadesc", "betadesc-nodesc")
#: the interval each round's rule names
INTERVAL = {1: "bootstrap", 2: "t"}


@dataclass(frozen=True)
class Axis:
    name: str     # the parameter, or "a+b+c" for a joint axis
    values: tuple  # the start's value first (a tuple of the parameters' values on a joint axis)
    params: tuple[str, ...] = ()  # the swept parameters (default: (name,))
    method: str = METHOD

    @property
    def swept(self) -> tuple[str, ...]:
        return self.params or (self.name,)

    def value_of(self, params: Mapping[str, Any]):
        """This axis's value in a full parameter dict (a tuple on a joint axis)."""
        vals = tuple(params[p] for p in self.swept)
        return vals if len(vals) > 1 else vals[0]


@dataclass(frozen=True)
class SearchSpace:
    start: dict[str, Any]  # the start's params as written (e.g. {"reading": "paper-literal"})
    axes: tuple[Axis, ...]
    scenes: tuple[str, ...]
    ratio: float
    reference: dict[str, Any]  # {"method": "random"}
    interval: str = "bootstrap"  # the round's interval (:data:`INTERVAL`)
    starts: dict[str, dict[str, Any]] = field(default_factory=dict)  # method -> start params as written


@dataclass
class AxisResult:
    axis: str
    incumbent: dict[str, Any]  # full params (start + adopted values) before this axis
    d: dict[tuple[Any, str], Paired] = field(default_factory=dict)  # (value, scene) -> D vs reference
    candidate: Any = None
    delta: dict[str, Paired] = field(default_factory=dict)  # scene -> candidate − incumbent
    adopted: bool = False
    method: str = METHOD
    axis_def: Axis | None = None

    @property
    def current(self):
        """The incumbent's value on this axis (a tuple on a joint axis)."""
        return self.axis_def.value_of(self.incumbent) if self.axis_def else self.incumbent[self.axis]

    @property
    def chosen(self):
        return self.candidate if self.adopted else self.current


def resolved(params: Mapping[str, Any], method: str = METHOD) -> dict[str, Any]:
    """The full, validated parameter dict of ``method`` for ``params`` (bundle applied)."""
    from methods.registry import get_pruner

    return get_pruner(method).parse_params(dict(params)).to_dict()


def search_space(raw: Mapping[str, Any], method: str = METHOD, interval: str = "bootstrap",
                 searched: tuple[str, ...] = (METHOD,)) -> SearchSpace:
    """The start(s) and axes encoded in a reading config (see the module docstring); ``searched``:
    the methods whose sweep entries are axes (round one: betadesc only)."""
    entries = [m for m in raw["methods"] if isinstance(m, Mapping) and m.get("name") in searched and m.get("sweep")]
    if not any(m["name"] == method for m in entries):
        raise ValueError(f"no sweep entries of {method} in the config")
    starts: dict[str, dict[str, Any]] = {}
    axes = []
    for m in entries:
        start = starts.setdefault(m["name"], dict(m.get("params") or {}))
        if dict(m.get("params") or {}) != start:
            raise ValueError(f"every axis entry of {m['name']} must sweep on the same start params")
        base = resolved(start, m["name"])
        names = tuple(m["sweep"])
        if len(names) == 1:
            axes.append(Axis(names[0], tuple([base[names[0]], *m["sweep"][names[0]]]), method=m["name"]))
            continue
        combos = list(itertools.product(*(m["sweep"][n] for n in names)))
        axes.append(Axis("+".join(names), tuple([tuple(base[n] for n in names), *combos]), names, m["name"]))
    scenes = tuple(s["name"] if isinstance(s, Mapping) else s for s in raw["scenes"])
    ratios = raw.get("ratios") or [0.3]
    return SearchSpace(starts[method], tuple(axes), scenes, float(ratios[0]), {"method": "random"},
                       interval, starts)


def with_value(incumbent: Mapping[str, Any], axis: str | Axis, value) -> dict[str, Any]:
    """``incumbent`` with ``axis`` (a name, or an :class:`Axis`: every parameter of a joint one) at ``value``."""
    if isinstance(axis, Axis) and axis.params:
        return {**incumbent, **dict(zip(axis.params, value))}
    return {**incumbent, (axis.name if isinstance(axis, Axis) else axis): value}


def _start(space: SearchSpace, method: str) -> dict[str, Any]:
    return space.starts.get(method, space.start) if space.starts else space.start


def _params_of(space: SearchSpace, method: str) -> list[str]:
    return list(dict.fromkeys(p for a in space.axes if a.method == method for p in a.swept))


def overrides(space: SearchSpace, params: Mapping[str, Any], method: str = METHOD) -> dict[str, Any]:
    """``params`` as the start plus the axis values that differ from the start's (config form)."""
    base = resolved(_start(space, method), method)
    return {**_start(space, method), **{p: params[p] for p in _params_of(space, method) if params[p] != base[p]}}


def label(space: SearchSpace, params: Mapping[str, Any], method: str = METHOD, prefix: str = "lit") -> str:
    """A short, stable variant name: ``prefix`` + the axis values that differ from the start."""
    extra = overrides(space, params, method)
    diff = [f"{p}={_fmt(extra[p])}" for p in _params_of(space, method) if p in extra]
    return prefix + ("+" + "+".join(diff) if diff else "")


def _fmt(v) -> str:
    if isinstance(v, tuple):
        return ", ".join(_fmt(x) for x in v)
    return format(v, "g") if isinstance(v, float) else str(v)


def _match(params: Mapping[str, Any], space: SearchSpace) -> dict[str, Any]:
    """The row-matching subset of full params: every value but the ``reading`` label (two rows with the
    same values and different bundle names are the same reading)."""
    return {k: v for k, v in params.items() if k != "reading"}


def missing(df: pd.DataFrame, space: SearchSpace, wanted: list[dict[str, Any]],
            method: str = METHOD) -> list[dict[str, Any]]:
    """The wanted full param dicts of ``method`` that have no ok rows on some selection scene."""
    rows = df[(df["status"] == "ok") & (df["method"] == method) & ((df["ratio"] - space.ratio).abs() < 1e-9)]
    have = {(r.scene, json.dumps(_match(json.loads(r.params), space), sort_keys=True))
            for r in rows[["scene", "params"]].drop_duplicates().itertuples()}
    out = []
    for p in wanted:
        key = json.dumps(_match(p, space), sort_keys=True)
        if any((s, key) not in have for s in space.scenes) and p not in out:
            out.append(p)
    return out


def evaluate_axis(df: pd.DataFrame, space: SearchSpace, axis: Axis, incumbent: dict[str, Any]) -> AxisResult:
    """One step of the rule (module docstring); ``incumbent`` holds the full params of ``axis.method``."""
    res = AxisResult(axis.name, dict(incumbent), method=axis.method, axis_def=axis)
    side = {v: {"method": axis.method, "params": _match(with_value(incumbent, axis, v), space)} for v in axis.values}
    current = axis.value_of(incumbent)

    def cmp(s, cand, ref):
        return compare(df, scene=s, ratio=space.ratio, candidate=cand, reference=ref, interval=space.interval)

    for v in axis.values:
        for s in space.scenes:
            res.d[(v, s)] = cmp(s, side[v], space.reference)
    others = [v for v in axis.values if v != current]
    mean_d = {v: sum(res.d[(v, s)].mean for s in space.scenes) / len(space.scenes) for v in others}
    res.candidate = max(others, key=lambda v: (mean_d[v], -others.index(v)))
    for s in space.scenes:
        res.delta[s] = cmp(s, side[res.candidate], side[current])
    res.adopted = all(p.n > 0 and p.mean > p.half_width for p in res.delta.values())
    return res


INTERVAL_TEXT = {"bootstrap": "95 % percentile-bootstrap CI (10,000 resamples of the views, seed 0)",
                 "t": "95 % Student-t interval (mean ± t₀.₉₇₅,ₙ₋₁·s/√n over the n views)"}


def selection_markdown(space: SearchSpace, steps: list[AxisResult], selected: Mapping[str, Mapping[str, Any]]) -> str:
    """The selection report; ``selected``: method -> the full params it ends with."""
    lines = [f"Criterion: D = mean paired per-view PSNR difference vs random at {space.ratio:.0%} pruning "
             f"(dB), with its {INTERVAL_TEXT[space.interval]}; `n` views used (`x` excluded at >= 100 dB).", ""]
    for i, st in enumerate(steps, 1):
        of = "" if st.method == METHOD else f" of `{st.method}`"
        lines += [f"### Axis {i}: `{st.axis}`{of} (incumbent `{_fmt(st.current)}`)", "",
                  "| value | " + " | ".join(f"D {s} [CI] (n/x)" for s in space.scenes) + " |",
                  "|---|" + "---|" * len(space.scenes)]
        values = list(dict.fromkeys(v for v, _ in st.d))
        for v in values:
            mark = " (incumbent)" if v == st.current else (" (candidate)" if v == st.candidate else "")
            cells = [f"{st.d[(v, s)].text()} ({st.d[(v, s)].n}/{st.d[(v, s)].n_excluded})" for s in space.scenes]
            lines.append(f"| `{_fmt(v)}`{mark} | " + " | ".join(cells) + " |")
        deltas = "; ".join(f"{s}: {p.text()} (half-width {p.half_width:.2f})" for s, p in st.delta.items())
        verdict = "**adopted**" if st.adopted else "not adopted (incumbent kept)"
        lines += ["", f"Candidate `{_fmt(st.candidate)}` − incumbent: {deltas} → {verdict}.", ""]
    lines += ["### Selected reading", "", "| method | parameter | value |", "|---|---|---|"]
    for method in dict.fromkeys(a.method for a in space.axes):
        lines += [f"| {method} | `{p}` | `{_fmt(selected[method][p])}` |" for p in _params_of(space, method)]
    return "\n".join(lines) + "\n"


def confirmation_markdown(df: pd.DataFrame, scenes: list[str], ratios: list[float],
                          sides: list[tuple[str, dict[str, Any]]], reference: Mapping[str, Any],
                          interval: str = "bootstrap") -> str:
    """Per scene and ratio, D vs ``reference`` with its interval for each named side (``{method, variant}``)."""
    lines = ["| scene | ratio | " + " | ".join(name for name, _ in sides) + " |",
             "|---|---|" + "---|" * len(sides)]
    for s in scenes:
        for r in ratios:
            cells = []
            for _, side in sides:
                try:
                    p = compare(df, scene=s, ratio=r, candidate=side, reference=reference, interval=interval)
                    cells.append(f"{p.text()} ({p.n}/{p.n_excluded})")
                except KeyError:
                    cells.append("n/a")
            lines.append(f"| {s} | {r:.0%} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
