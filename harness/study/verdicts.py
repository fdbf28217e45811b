"""What a claim's numbers say: estimates with their 95 % interval, an interval against a claimed band,
the verdict rules of :mod:`harness.study.claims` (documented there), and the run's cells.

* :class:`Estimate` — a mean with its t interval (:func:`harness.report.stats.mean_ci`) over n values;
  :func:`pooled` — the mean of per-scene means with the t interval over the scenes;
* :func:`outcome` — ``holds`` (the interval inside the band), ``fails`` (entirely outside),
  ``unclear`` (it straddles a bound); :func:`combine` — several comparisons that must all hold;
* :func:`verdict_per_scene`, :func:`verdict_average` — a claim's verdict from its scenes or its pooled interval;
* :class:`Run` — measured rows by (scene, method, variant, ratio), paired differences and levels;
* :class:`Result` — one claim's comparisons per scene, pooled, and its verdict (:meth:`Result.decide`);
  :func:`comparisons` fills it from cell pairs, :func:`need` names the cells a run lacks.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.report import cells, stats

INF = math.inf
HOLDS, FAILS, UNCLEAR = "holds", "fails", "unclear"
MARK = {HOLDS: "✓", FAILS: "✗", UNCLEAR: "?"}


@dataclass(frozen=True)
class Estimate:
    """Δ (or a level) with its 95 % interval over n values."""

    mean: float
    lo: float
    hi: float
    n: int

    def text(self, digits: int = 2) -> str:
        if not self.n or not np.isfinite(self.mean):
            return "–"
        ci = f" [{self.lo:+.{digits}f}, {self.hi:+.{digits}f}]" if np.isfinite(self.lo) else ""
        return f"{self.mean:+.{digits}f}{ci}"


def estimate(values) -> Estimate:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    lo, hi = stats.mean_ci(v) if v.size >= 2 else (np.nan, np.nan)
    return Estimate(float(v.mean()) if v.size else np.nan, lo, hi, int(v.size))


def pooled(per_scene: dict[str, Estimate]) -> Estimate:
    """Mean of the scene means, t interval over the k scenes (one scene: its own estimate)."""
    means = [e.mean for e in per_scene.values() if e.n and np.isfinite(e.mean)]
    if len(means) == 1:
        return next(e for e in per_scene.values() if e.n and np.isfinite(e.mean))
    return estimate(means)


def outcome(e: Estimate, band: tuple[float, float]) -> str:
    """holds: the interval inside the band; fails: entirely outside; unclear: it straddles a bound."""
    lo_b, hi_b = band
    if not (e.n and np.isfinite(e.lo) and np.isfinite(e.hi)):
        if e.n == 1 and np.isfinite(e.mean):  # a single value (zero-width): judged by itself
            e = Estimate(e.mean, e.mean, e.mean, 1)
        else:
            return UNCLEAR
    if e.lo > lo_b and e.hi <= hi_b:
        return HOLDS
    if e.hi <= lo_b or e.lo > hi_b:
        return FAILS
    return UNCLEAR


def combine(outcomes: list[str]) -> str:
    """Several comparisons that must all hold: fails if any fails, holds if all hold."""
    if FAILS in outcomes:
        return FAILS
    return HOLDS if outcomes and all(o == HOLDS for o in outcomes) else UNCLEAR


def verdict_per_scene(per_scene: dict[str, str]) -> str:
    got = set(per_scene.values())
    if not got:
        return "not testable here"
    if got == {HOLDS}:
        return "holds"
    if got == {FAILS}:
        return "fails"
    if HOLDS in got and FAILS in got:
        return "mixed"
    return "inconclusive"


def verdict_average(pooled_outcome: str) -> str:
    return {HOLDS: "holds", FAILS: "fails"}.get(pooled_outcome, "inconclusive")


# --------------------------------------------------------------------------- the run's cells
@dataclass
class Run:
    """Measured rows with the ``near`` flag (:func:`harness.report.cells.prepare`), indexed by cell."""

    ok: pd.DataFrame
    groups: dict = field(default_factory=dict)
    labels: dict = field(default_factory=dict)

    @classmethod
    def of(cls, df: pd.DataFrame) -> "Run":
        ok, _ = cells.prepare(df)
        groups = {k: g for k, g in ok.groupby(["scene", "method", "variant", "rkey"], sort=False)}
        return cls(ok, groups, dict(zip(ok["scene"], ok["label"])))

    def cell(self, scene, method, ratio, variant="default"):
        return self.groups.get((scene, method, variant, ratios.key(ratio)))

    def diff(self, scene, a: tuple, b: tuple, metric="psnr") -> Estimate | None:
        """Δ = cell a − cell b (each (method, ratio[, variant])), paired per view; None if either is missing."""
        ga, gb = self.cell(scene, *a), self.cell(scene, *b)
        if ga is None or gb is None or metric not in ga:
            return None
        d, _ = stats.paired_diffs(ga, gb, metric)
        return estimate(d) if d.size else None

    def level(self, scene, method, ratio, metric) -> Estimate | None:
        g = self.cell(scene, method, ratio)
        if g is None or metric not in g or g[metric].isna().all():
            return None
        return estimate(pd.to_numeric(g[metric], errors="coerce"))

    def splats(self, scene) -> float:
        s = self.ok.loc[self.ok["scene"] == scene, "splats_in"]
        return float(s.max()) if len(s) else np.nan

    def variant_with(self, method, ratio, key, value) -> str | None:
        """The variant of ``method`` at ``ratio`` whose params equal the default's except ``key`` = ``value``."""
        rows = self.ok[(self.ok["method"] == method) & (self.ok["rkey"] == ratios.key(ratio))]
        params = {v: json.loads(p or "{}") for v, p in zip(rows["variant"], rows["params"])}
        base = params.get("default")
        if base is None:
            return None
        for v, p in params.items():
            if _close(p.get(key), value) and {k: x for k, x in p.items() if k != key} == \
                    {k: x for k, x in base.items() if k != key}:
                return v
        return None


def _close(a, b) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return abs(float(a) - float(b)) <= 1e-9 * max(1.0, abs(float(b)))
    return a == b


@dataclass
class Result:
    key: str
    claim: str
    paper: str
    at: str
    unit: str  # "scene", "average" or "split"
    band: tuple[float, float] = (-INF, INF)
    per_scene: dict[str, list[tuple[str, Estimate]]] = field(default_factory=dict)
    pooled: dict[str, Estimate] = field(default_factory=dict)
    verdict: str = "not testable here"
    why: str = ""
    digits: int = 2
    note: str = ""

    def scene_outcome(self, scene: str) -> str:
        return combine([outcome(e, self.band) for _, e in self.per_scene[scene]])

    def decide(self) -> "Result":
        if self.why:
            self.verdict = "not testable here"
            return self
        if not self.per_scene:
            self.verdict, self.why = "not testable here", "no scene has the cells this claim needs"
            return self
        names = list(dict.fromkeys(n for comps in self.per_scene.values() for n, _ in comps))
        self.pooled = {n: pooled({s: e for s, comps in self.per_scene.items() for m, e in comps if m == n})
                       for n in names}
        per = {s: self.scene_outcome(s) for s in self.per_scene}
        if self.unit == "scene":
            self.verdict = verdict_per_scene(per)
        elif self.unit == "split":
            up = any(e.n and e.lo > 0 for comps in self.per_scene.values() for _, e in comps)
            down = any(e.n and e.hi < 0 for comps in self.per_scene.values() for _, e in comps)
            same = all(o != UNCLEAR for o in (outcome(e, (0, INF)) for c in self.per_scene.values() for _, e in c))
            self.verdict = "holds" if up and down else ("fails" if same else "inconclusive")
        else:
            self.verdict = verdict_average(combine([outcome(e, self.band) for e in self.pooled.values()]))
        return self


def comparisons(run: Run, res: Result, specs, metric: str = "psnr") -> Result:
    """Fill ``res.per_scene`` from ``specs``: [(name, a(scene) -> cell | None, b(scene) -> cell | None)]."""
    empty = []
    for scene in run.labels:
        got = []
        for name, a, b in specs:
            ca, cb = a(scene), b(scene)
            e = run.diff(scene, ca, cb, metric) if ca and cb else None
            if e is not None:
                got.append((name, e))
            elif ca and cb and run.cell(scene, *ca) is not None and run.cell(scene, *cb) is not None:
                empty.append(run.labels[scene])  # both measured, every pair near-identical
        if len(got) == len(specs):
            res.per_scene[scene] = got
    if empty:
        res.note = "; ".join(filter(None, [res.note, "left out, every view pair near-identical (≥ 100 dB): "
                                           + ", ".join(dict.fromkeys(empty))]))
    return res


def need(run: Run, res: Result, cells_needed: list[tuple[str, float]]) -> Result:
    missing = list(dict.fromkeys(f"{m} at {ratios.percent(r)}" for m, r in cells_needed
                                 if not any(run.cell(s, m, r) is not None for s in run.labels)))
    if missing:
        res.why = "the run has no " + ", ".join(missing)
    return res
