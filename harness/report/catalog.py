"""What tables and plots need to know about methods and metrics, asked of the registries.

Methods a run measured but the registry does not know (a plugin no longer installed) still show,
under their own name, in the ``other`` group.
"""

from __future__ import annotations

import contextvars
import json
from contextlib import contextmanager
from dataclasses import dataclass

import pandas as pd

from harness.metrics.registry import METRICS
from methods.registry import GROUPS, PRUNERS, ablation_grid

#: the comparison table's groups (ablations have their own table)
COMPARISON_GROUPS = tuple(g for g in GROUPS if g != "ablation")
#: the method every other is compared with, view by view, in the comparison and versus tables
#: (``harness tables/report --reference`` picks another)
DEFAULT_REFERENCE = "random"


def _spec(name: str):
    try:
        return PRUNERS.get(name)
    except KeyError:
        return None


_NOTES: contextvars.ContextVar[dict] = contextvars.ContextVar("method_notes", default={})


@contextmanager
def budget_notes(df: pd.DataFrame):
    """Within the block, :func:`method_label` appends each method's budget note for these results
    (from the parameters of its ``default`` variant, :attr:`methods.registry.PrunerSpec.budget_note`):
    "ConfSplatPrune — lower bound (100 iterations)" in every table, plot and the report page."""
    notes = {}
    if {"method", "variant", "params"} <= set(df.columns):
        rows = df[df["variant"] == "default"].drop_duplicates("method")
        for method, text in zip(rows["method"], rows["params"]):
            spec = _spec(method)
            if spec is None or not text:
                continue
            try:
                note = spec.budget_note(spec.parse_params(json.loads(text)))
            except (ValueError, TypeError):
                continue
            if note:
                notes[method] = note
    token = _NOTES.set(notes)
    try:
        yield notes
    finally:
        _NOTES.reset(token)


def method_label(name: str) -> str:
    spec = _spec(name)
    label = spec.label if spec is not None else name
    note = _NOTES.get().get(name)
    return f"{label} — {note}" if note else label


def method_order(names) -> list[str]:
    """``names`` ordered by group (:data:`methods.registry.GROUPS`), then registration order."""
    registered = {s.name: i for i, s in enumerate(PRUNERS)}
    group_rank = {g: i for i, g in enumerate(GROUPS)}

    def key(name):
        spec = _spec(name)
        return (group_rank[spec.group] if spec else len(GROUPS), registered.get(name, len(registered)), name)

    return sorted(dict.fromkeys(names), key=key)


def comparison_methods(present) -> list[tuple[str, str]]:
    """(group title, method) of the comparison table's columns, for the methods ``present``."""
    out = []
    for name in method_order(present):
        spec = _spec(name)
        group = spec.group if spec else "other"
        if group in COMPARISON_GROUPS:
            out.append((GROUPS[group], name))
    return out


@dataclass(frozen=True)
class AblationCell:
    """One cell of the paper's ablation grid: its descriptors and Beta labels, and the method there."""

    descriptors: str
    beta: str
    method: str

    @property
    def column(self) -> tuple[str, str]:
        """Its column in the wide table: (descriptors, Beta)."""
        return (self.descriptors, self.beta)

    @property
    def heading(self) -> str:
        """Its column in the per-metric sections: ``descriptors · Beta``."""
        return f"{self.descriptors} · {self.beta}"


def ablation_cells() -> list[AblationCell]:
    """The cells of the ablation grid, the full method last."""
    grid = ablation_grid()
    order = [(False, False), (False, True), (True, False), (True, True)]
    return [AblationCell(*grid[k].ablation.labels, grid[k].name) for k in order if k in grid]


def _pair(without: tuple[bool, bool]) -> tuple[str, str] | None:
    grid = ablation_grid()
    if without in grid and (True, True) in grid:
        return grid[without].name, grid[(True, True)].name
    return None


def descriptor_pair() -> tuple[str, str] | None:
    """(method without descriptors, the full method), both with the Beta score."""
    return _pair((False, True))


def beta_pair() -> tuple[str, str] | None:
    """(method without the Beta score, the full method), both with descriptors."""
    return _pair((True, False))


def proposed_method() -> str | None:
    spec = ablation_grid().get((True, True))
    return spec.name if spec else None


def metric_columns(present) -> list[tuple[str, str, int]]:
    """(name, heading, digits) of the registered metrics among ``present``, registry order."""
    return [(m.name, m.heading, m.digits) for m in METRICS if m.name in set(present)]


def display_metrics(present) -> list[tuple[str, str, int]]:
    """:func:`metric_columns` with each occupancy-masked variant right after the full-frame metric
    it is registered to restrict (its ``masks``): OM-PSNR beside PSNR."""
    cols = metric_columns(present)
    names = [c[0] for c in cols]
    base = {n: m for n in names if (m := METRICS.get(n).masks) in names}
    out = [c for c in cols if c[0] not in base]
    for c in cols:
        if c[0] in base:
            at = next(i for i, o in enumerate(out) if o[0] == base[c[0]])
            while at + 1 < len(out) and base.get(out[at + 1][0]) == base[c[0]]:
                at += 1
            out.insert(at + 1, c)
    return out


def masked_of(metric: str) -> str | None:
    """The full-frame metric an occupancy-masked ``metric`` restricts (None for others)."""
    return METRICS.get(metric).masks


def higher_is_better(metric: str) -> bool:
    return METRICS.get(metric).higher_is_better
