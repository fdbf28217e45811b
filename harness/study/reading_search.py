"""The pre-registered greedy selection of a pruner's parameters: BetaDescPrune's reading (round one:
``ctc_configs/study/reading.yaml``, round two: ``ctc_configs/study/reading2.yaml``) and the virtual rig's
geometry and betadesc-vr's weight (``ctc_configs/study/virtualrig.yaml``); each rule is in its file's header.

Pure functions over a run config's raw mapping and the tidy results of its runs; the drivers that
run the stages are ``harness bench reading`` (:mod:`harness.study.bench.reading`; named
tools/reading_search.py when round one was pre-registered in commit 70c2edb) and ``harness bench
virtualrig`` (:mod:`harness.study.bench.virtualrig`).

* :func:`search_space` reads the rule's start (the ``params`` of the first sweep entry of each
  searched method: ``betadesc``; in round two also ``betadesc-nodesc``; ``virtual-rig``, then
  ``betadesc-vr``, for the virtual rig) and the axes (one per sweep entry, in file order). An axis
  sweeps one parameter (its values, the start's value first) or, in round two, several at once: a
  *joint* axis whose values are the tuples of the sweep's combinations (the start's tuple first),
  named ``a+b+c``. The space also holds the rule's reference side (``random``; ``lightgs`` for the
  virtual rig), the view protocols it reads (all; ``shifted`` and ``independent`` pooled for the
  virtual rig), its interval and the variant-name prefix of the stage configs.
* :func:`evaluate_axis` computes, for one axis on the current incumbent of its method, D (vs the
  reference) with its 95 % interval for every value on every selection scene, the candidate
  (highest mean D over the scenes among the non-incumbent values) and the paired candidate −
  incumbent difference with its interval; the candidate is adopted iff that mean exceeds the
  interval's half-width on every selection scene (with ``ignore_unchanged``, the virtual rig's rule:
  on every scene where the candidate changes anything — an exactly zero difference with a zero-width
  interval means the axis does not apply there — and on at least one). The interval is the round's:
  the percentile bootstrap in round one and for the virtual rig (their rules), the t interval in
  round two (:mod:`harness.study.paired`).
* :func:`selection_markdown` and :func:`confirmation_markdown` write the report tables.
"""

from __future__ import annotations

import itertools
import json
from dataclasses import dataclass, field
from typing import Any, Mapping

import pandas as pd

from harness.study.paired import Paired, compare

METHOD = "betadesc"
#: the methods whose sweep entries are axes in round two (round one used only the first)
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
    starts: dict[str, dict[str, Any]]  # searched method -> its start params as written
    axes: tuple[Axis, ...]
    scenes: tuple[str, ...]
    ratio: float
    reference: dict[str, Any] = field(default_factory=lambda: {"method": "random"})
    interval: str = "bootstrap"  # the rule's interval (:data:`INTERVAL`)
    method: str = METHOD  # the searched method the rule is about (the report names the others)
    prefix: str = "lit"  # variant-name prefix of the searched readings in stage configs
    protocols: tuple[str, ...] = ()  # the view protocols the rule reads, pooled (empty: every view)

    @property
    def start(self) -> dict[str, Any]:
        """The start params of :attr:`method` as written (e.g. ``{"reading": "paper-literal"}``)."""
        return self.starts[self.method]


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


def search_space(raw: Mapping[str, Any], method: str = METHOD, *, reference: Mapping[str, Any] | None = None,
                 prefix: str = "lit", interval: str = "bootstrap", searched: tuple[str, ...] | None = None,
                 protocols: tuple[str, ...] = ()) -> SearchSpace:
    """The start(s) and axes encoded in a selection config (see the module docstring); ``searched``:
    the methods whose sweep entries are axes (default: ``method`` alone, as round one and the virtual rig)."""
    searched = searched or (method,)
    entries = [m for m in raw["methods"] if isinstance(m, Mapping) and m.get("name") in searched and m.get("sweep")]
    if not any(m["name"] == method for m in entries):
        raise ValueError(f"no sweep entries of {method} in the config")
    starts: dict[str, dict[str, Any]] = {}
    for m in entries:  # the start: every entry's params agree (an entry leaves out the parameter it sweeps)
        start = starts.setdefault(m["name"], {})
        for k, v in dict(m.get("params") or {}).items():
            if start.setdefault(k, v) != v:
                raise ValueError(f"every axis entry of {m['name']} must sweep on the same start params ({k})")
    axes = []
    for m in entries:
        start = starts[m["name"]]
        if set(start) - set(m.get("params") or {}) - set(m["sweep"]):
            raise ValueError(f"every axis entry of {m['name']} must sweep on the same start params "
                             f"(missing {sorted(set(start) - set(m.get('params') or {}) - set(m['sweep']))})")
        base = resolved(start, m["name"])
        names = tuple(m["sweep"])
        if len(names) == 1:
            axes.append(Axis(names[0], tuple([base[names[0]], *m["sweep"][names[0]]]), method=m["name"]))
            continue
        combos = list(itertools.product(*(m["sweep"][n] for n in names)))
        axes.append(Axis("+".join(names), tuple([tuple(base[n] for n in names), *combos]), names, m["name"]))
    scenes = tuple(s["name"] if isinstance(s, Mapping) else s for s in raw["scenes"])
    ratios = raw.get("ratios") or [0.3]
    return SearchSpace(starts, tuple(axes), scenes, float(ratios[0]), dict(reference or {"method": "random"}),
                       interval, method, prefix, tuple(protocols))


def with_value(incumbent: Mapping[str, Any], axis: str | Axis, value) -> dict[str, Any]:
    """``incumbent`` with ``axis`` (a name, or an :class:`Axis`: every parameter of a joint one) at ``value``."""
    if isinstance(axis, Axis) and axis.params:
        return {**incumbent, **dict(zip(axis.params, value))}
    return {**incumbent, (axis.name if isinstance(axis, Axis) else axis): value}


def _params_of(space: SearchSpace, method: str) -> list[str]:
    return list(dict.fromkeys(p for a in space.axes if a.method == method for p in a.swept))


def selected_values(space: SearchSpace, incumbents: Mapping[str, Mapping[str, Any]]) -> dict[str, dict[str, Any]]:
    """method -> {searched parameter: its value in ``incumbents[method]``} (full params per method)."""
    return {m: {p: incumbents[m][p] for p in _params_of(space, m)} for m in space.starts}


def overrides(space: SearchSpace, params: Mapping[str, Any], method: str | None = None) -> dict[str, Any]:
    """``params`` of ``method`` (default: the space's) as its start plus the searched values that differ
    from the start's (config form)."""
    method = method or space.method
    start = space.starts[method]
    base = resolved(start, method)
    return {**start, **{p: params[p] for p in _params_of(space, method) if params[p] != base[p]}}


def label(space: SearchSpace, params: Mapping[str, Any], method: str | None = None) -> str:
    """A short, stable variant name: the space's prefix + the searched values that differ from the start."""
    method = method or space.method
    extra = overrides(space, params, method)
    diff = [f"{p}={_fmt(extra[p])}" for p in _params_of(space, method) if p in extra]
    return space.prefix + ("+" + "+".join(diff) if diff else "")


def _fmt(v) -> str:
    if isinstance(v, tuple):
        return ", ".join(_fmt(x) for x in v)
    return format(v, "g") if isinstance(v, float) else str(v)


def _match(params: Mapping[str, Any]) -> dict[str, Any]:
    """The row-matching subset of full params: every value but the ``reading`` label (two rows with the
    same values and different bundle names are the same reading)."""
    return {k: v for k, v in params.items() if k != "reading"}


def missing(df: pd.DataFrame, space: SearchSpace, wanted: list[dict[str, Any]],
            method: str | None = None) -> list[dict[str, Any]]:
    """The wanted full param dicts of ``method`` (default: the space's) that have no ok rows on some
    selection scene."""
    method = method or space.method
    rows = df[(df["status"] == "ok") & (df["method"] == method) & ((df["ratio"] - space.ratio).abs() < 1e-9)]
    have = {(r.scene, json.dumps(_match(json.loads(r.params)), sort_keys=True))
            for r in rows[["scene", "params"]].drop_duplicates().itertuples()}
    out = []
    for p in wanted:
        key = json.dumps(_match(p), sort_keys=True)
        if any((s, key) not in have for s in space.scenes) and p not in out:
            out.append(p)
    return out


def _unchanged(p: Paired) -> bool:
    """Every view's PSNR identical on both sides: the axis does not apply to the scene."""
    return p.n > 0 and p.mean == 0 and p.half_width == 0


def evaluate_axis(df: pd.DataFrame, space: SearchSpace, axis: Axis, incumbent: dict[str, Any], *,
                  ignore_unchanged: bool = False) -> AxisResult:
    """One step of the rule (module docstring) on the views of the space's protocols; ``incumbent``
    holds the full params of ``axis.method``."""
    if space.protocols:
        df = df[df["protocol"].isin(space.protocols)]
    res = AxisResult(axis.name, dict(incumbent), method=axis.method, axis_def=axis)
    side = {v: {"method": axis.method, "params": _match(with_value(incumbent, axis, v))} for v in axis.values}
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
    judged = [p for p in res.delta.values() if not (ignore_unchanged and _unchanged(p))]
    res.adopted = bool(judged) and all(p.n > 0 and p.mean > p.half_width for p in judged)
    return res


INTERVAL_TEXT = {"bootstrap": "95 % percentile-bootstrap CI (10,000 resamples of the views, seed 0)",
                 "t": "95 % Student-t interval (mean ± t₀.₉₇₅,ₙ₋₁·s/√n over the n views)"}


def _views_text(protocols: tuple[str, ...]) -> str:
    if not protocols:
        return ""
    names = protocols[0] if len(protocols) == 1 else ", ".join(protocols[:-1]) + " and " + protocols[-1]
    return f" over the held-out views of the {names} protocol" + ("s pooled" if len(protocols) > 1 else "")


def selection_markdown(space: SearchSpace, steps: list[AxisResult], selected: Mapping[str, Mapping[str, Any]]) -> str:
    """The selection report; ``selected``: method -> the full params it ends with. The selected values:
    a row per axis when one method is searched, a row per method and parameter when several are."""
    ref = space.reference.get("method", "the reference")
    lines = [f"Criterion: D = mean paired per-view PSNR difference vs {ref} at {space.ratio:.0%} pruning "
             f"(dB){_views_text(space.protocols)}, with its {INTERVAL_TEXT[space.interval]}; `n` views used "
             "(`x` excluded at >= 100 dB).", ""]
    for i, st in enumerate(steps, 1):
        of = "" if st.method == space.method else f" of `{st.method}`"
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
    lines += ["### Selected " + ("reading" if space.method == METHOD else "parameters"), ""]
    if len(space.starts) == 1:
        lines += ["| axis | value |", "|---|---|"]
        lines += [f"| `{a.name}` | `{_fmt(a.value_of(selected[a.method]))}` |" for a in space.axes]
    else:
        lines += ["| method | parameter | value |", "|---|---|---|"]
        for method in space.starts:
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
