"""The cells a claim reads from a run's rows, under one reading, and their paired differences.

**Cells under a reading.** BetaDescPrune and its ablations are read from the variant whose
parameters are exactly that reading's (``paper-literal``: the default; ``paper-direction``: a
variant the config names ``{reading: paper-direction}``); a method whose parameters do not depend on
the reading except for its name (the no-descriptor variants: they compute no ℓ, s, u) from its
default variant under both; a sweep's value from the variant that differs from the reading's in the
swept parameter only. Camera-aware methods and baselines: their default variant. A reading the run
did not measure makes the claim "not testable here" under it.

**Paired per-view differences, near-identical views.** Δ of a comparison on a scene is the mean of
PSNR(a, v) − PSNR(b, v) over the held-out views v both cells were measured on. A PSNR of
≥ :data:`CAP_DB` (inf: identical images) is capped at :data:`CAP_DB`: a pair where only one side is
near-identical (e.g. a lossless camera-aware cell against a lossy BetaDesc one) is kept with that
side at 100 dB; a pair identical on both sides (both ≥ 100 dB) carries no information and leaves,
counted (``dropped``; ``capped`` counts the kept pairs that were capped).

**The best camera-aware method** of a scene and ratio: the one with the higher mean PSNR over its
views (capped as above), chosen before Δ is computed (the paper's comparison is with the stronger
of the two).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.report import catalog, cells
from harness.study import rules
from harness.study.claim_list import Claim
from harness.study.rules import Estimate, Mark
from methods.registry import GROUPS

CAP_DB = 100.0
POOLED = "pooled over scenes"
READINGS = ("paper-literal", "paper-direction")


@dataclass(frozen=True)
class Cell:
    """(method, variant, ratio): one measured cell of the run."""

    method: str
    variant: str
    ratio: float

    @property
    def id(self) -> str:
        return f"{self.method}:{self.variant}@{ratios.key(self.ratio):g}"


@dataclass
class Row:
    """One estimate of a claim: a scene's comparison (or the pooled one), with its mark."""

    name: str
    scene: str
    est: Estimate
    a: str = ""
    b: str = ""
    test: str = ""
    dropped: int = 0
    capped: int = 0
    mark: Mark | None = None


@dataclass
class Evaluation:
    """A claim under one reading: its rows per scene, pooled rows, verdict(s), why, notes."""

    claim: Claim
    reading: str
    rows: list[Row] = field(default_factory=list)
    pooled: list[Row] = field(default_factory=list)
    verdict: str = "not testable here"
    verdicts: dict = field(default_factory=dict)
    why: str = ""
    notes: list[str] = field(default_factory=list)
    k: int = 0
    left_out: dict = field(default_factory=dict)  # scene -> pairs identical on both sides, when none was left


class Run:
    """Measured rows by (scene, method, variant, ratio key); paired differences and levels."""

    def __init__(self, df: pd.DataFrame):
        ok, _ = cells.prepare(df)
        self.ok = ok
        self.groups = {k: g for k, g in ok.groupby(["scene", "method", "variant", "rkey"], sort=False)}
        self.labels = dict(zip(ok["scene"], ok["label"]))
        self.params = {(m, v): json.loads(p or "{}") for m, v, p in zip(ok["method"], ok["variant"], ok["params"])}
        side = ok[["width", "height"]].max(axis=1) if {"width", "height"} <= set(ok) else pd.Series(dtype=float)
        self.sides = {s: set(pd.to_numeric(side[ok["scene"] == s], errors="coerce").dropna().astype(int))
                      for s in self.labels}

    def rows_of(self, scene: str, cell: Cell):
        return self.groups.get((scene, cell.method, cell.variant, ratios.key(cell.ratio)))

    def measured(self, cell: Cell) -> bool:
        return any(self.rows_of(s, cell) is not None for s in self.labels)

    def reading_variant(self, method: str, reading: str) -> str | None:
        """The variant of ``method`` whose parameters are exactly ``reading``'s (module doc)."""
        from methods import get_pruner

        try:
            spec = get_pruner(method)
            want = _plain(spec.parse_params({"reading": reading}).to_dict())
            default = _plain(spec.parse_params().to_dict())
        except (KeyError, ValueError):  # not a pruner with readings
            return "default" if reading == READINGS[0] else None
        if _without(want, "reading") == _without(default, "reading"):
            want = default  # its parameters do not depend on the reading: the default cells serve
        found = [v for (m, v), p in self.params.items() if m == method and p == want]
        return ("default" if "default" in found else sorted(found)[0]) if found else None

    def sweep_variant(self, method: str, base: str, key: str, value) -> str | None:
        """The variant of ``method`` equal to ``base`` except ``key`` = ``value`` (``base`` itself if equal)."""
        ref = self.params.get((method, base))
        if ref is None:
            return None
        if _close(ref.get(key), value):
            return base
        for (m, v), p in self.params.items():
            if m == method and _close(p.get(key), value) and _without(p, key) == _without(ref, key):
                return v
        return None

    def splats(self, scene: str) -> float:
        s = self.ok.loc[self.ok["scene"] == scene, "splats_in"]
        return float(s.max()) if len(s) else np.nan

    def capped(self, scene: str, cell: Cell, metric: str = "psnr") -> pd.Series | None:
        g = self.rows_of(scene, cell)
        if g is None or metric not in g:
            return None
        v = pd.to_numeric(g[metric], errors="coerce").astype(np.float64)
        v.index = list(zip(g["frame"], g["view"]))
        return v.clip(upper=CAP_DB) if metric == "psnr" else v

    def diff(self, scene: str, a: Cell, b: Cell, metric: str = "psnr") -> Row | None:
        """Δ = a − b paired per view, near-identical pairs capped or dropped (module doc)."""
        va, vb = self.capped(scene, a, metric), self.capped(scene, b, metric)
        if va is None or vb is None:
            return None
        both = va.index.intersection(vb.index, sort=False)
        x, y = va[both].to_numpy(), vb[both].to_numpy()
        keep = np.isfinite(x) & np.isfinite(y)
        x, y = x[keep], y[keep]
        identical = (x >= CAP_DB) & (y >= CAP_DB) if metric == "psnr" else np.zeros(len(x), bool)
        capped = int(((x >= CAP_DB) ^ (y >= CAP_DB)).sum()) if metric == "psnr" else 0
        d = (x - y)[~identical]
        return Row("", scene, rules.of_values(d), a.id, b.id, dropped=int(identical.sum()), capped=capped)

    def level(self, scene: str, a: Cell, metric: str) -> Row | None:
        v = self.capped(scene, a, metric)
        if v is None or v.isna().all():
            return None
        return Row("", scene, rules.of_values(v.to_numpy()), a.id)

    def mean_psnr(self, scene: str, cell: Cell) -> float:
        v = self.capped(scene, cell)
        return float(v.mean()) if v is not None and v.notna().any() else np.nan


def _plain(d: dict) -> dict:
    return json.loads(json.dumps(d))


def _without(p: dict, key: str) -> dict:
    return {k: v for k, v in p.items() if k != key}


def _close(a, b) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return abs(float(a) - float(b)) <= 1e-9 * max(1.0, abs(float(b)))
    return a == b


def roles(run: Run, reading: str) -> dict[str, Cell | None]:
    """The ablation grid's four methods under ``reading`` (a Cell factory per role, ratio filled later)."""
    from methods.registry import ablation_grid

    grid = {k: spec.name for k, spec in ablation_grid().items()}
    names = {"full": grid.get((True, True)), "nodesc": grid.get((False, True)), "nobeta": grid.get((True, False)),
             "neither": grid.get((False, False))}
    return {role: (m, run.reading_variant(m, reading)) if m else None for role, m in names.items()}


def camera_aware(run: Run) -> list[str]:
    return [m for grp, m in catalog.comparison_methods(run.ok["method"]) if grp == GROUPS["camera-aware"]]


def best_camera(run: Run, scene: str, ratio: float) -> Cell | None:
    best = None
    for m in camera_aware(run):
        mean = run.mean_psnr(scene, Cell(m, "default", ratio))
        if np.isfinite(mean) and (best is None or mean > best[0]):
            best = (mean, m)
    return Cell(best[1], "default", ratio) if best else None
