"""The cell tables of the paper (:class:`harness.report.cells.CellTable`, cells against a reference row).

* ``comparison`` (paper Table 1): each comparison-group method's default variant at Low/Mid/High =
  10/20/30 % pruning; reference: ``random`` (:data:`catalog.DEFAULT_REFERENCE`, or ``--reference``)
  at the same ratio.
* ``ablation`` (paper Table 2): the descriptors × Beta grid at 20 % (:class:`~harness.report.catalog.AblationCell`);
  reference: the full method (``betadesc``) at 20 %, so Δ < 0 in the higher-is-better sense means the
  removed part helped. Bold: the best mean of a row.
* ``versus``: every measured (method, variant, ratio) against the reference method at the same
  ratio, per scene and pooled over scenes (the random-effects mean of the scene means with its HKSJ
  interval, near-identical pairs left out), with a verdict per row: on how many scenes the CI lies
  above / below 0.
* ``per_scene``: the descriptor gain betadesc − betadesc-nodesc at keep 0.7/0.5/0.3 per scene
  (positive = descriptors help; the paper's "+4.04 dB" sense), paired per view.
"""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd

from harness.core import ratios
from harness.report import catalog, stats
from harness.report.catalog import AblationCell
from harness.report.cells import (
    KEEPS,
    NEAR,
    POOLED,
    SIZE_HEADING,
    CellTable,
    caption,
    cell_text,
    delta_text,
    mean_text,
    notes_for,
    prepare,
    wide,
)
from harness.report.tabledata import Missing, Table

LEVELS = (("Low", 0.1), ("Mid", 0.2), ("High", 0.3))
ABLATION_RATIO = 0.2


def _delta_only(r, digits: int) -> str:
    """Δ [CI] alone, ``‡`` when pairs were left out as near-identical."""
    return delta_text(r, digits).removeprefix("Δ ") + (NEAR if r["n_pairs_excluded"] else "")


def _comparison_columns(ok: pd.DataFrame) -> list[tuple]:
    """(group, method, level, ratio) of every comparison-group method measured at a level's ratio."""
    measured = {(m, k) for m, k in zip(ok.loc[ok["variant"] == "default", "method"],
                                       ok.loc[ok["variant"] == "default", "rkey"])}
    return [(grp, m, lvl, r) for grp, m in catalog.comparison_methods(ok["method"]) for lvl, r in LEVELS
            if (m, ratios.key(r)) in measured]


def table_comparison(df: pd.DataFrame, reference: str | None = None):
    reference = reference or catalog.DEFAULT_REFERENCE
    ok, mets = prepare(df)
    cols = _comparison_columns(ok)
    if not cols:
        return Missing("no method of the comparison groups was measured at 10/20/30 % pruning")
    levels = {ratios.key(r): f"{lvl} ({ratios.percent(r)})" for lvl, r in LEVELS}
    spec = CellTable("comparison", [(m, "default", r) for *_, m, _, r in cols], lambda c: (reference, "default", c[2]),
                     (["Dataset", "Method"], ["label", "method_label"]), lambda r: r["level"],
                     lambda t: [levels[ratios.key(r)] for _, r in LEVELS if ratios.key(r) in set(t["ratio"])],
                     levels=levels)
    tidy = spec.tidy(ok, mets)
    secs = spec.sections(tidy, mets, lambda r, dg: cell_text(r, dg, r["method"] == reference))
    secs += spec.size_section(tidy)
    wide_cols = pd.MultiIndex.from_tuples([(g, catalog.method_label(m), lvl) for g, m, lvl, _ in cols],
                                          names=["group", "method", "level"])
    column_of = {}
    for c, (_, m, _, r) in zip(wide_cols, cols):
        column_of.setdefault((m, ratios.key(r)), c)
    sizes = [("splats", "splats", 0), ("bytes", "bytes", 0)] if secs[-1][0] == SIZE_HEADING else []
    disp = wide(tidy, mets, wide_cols, lambda r: column_of[(r["method"], r["ratio"])], mean_text, sizes)
    warn = [] if reference in set(ok["method"]) else \
        [f"comparison: reference method {reference} not measured; cells show means without Δ"]
    return Table(disp, notes_for(tidy, catalog.method_label(reference)), tidy, secs, warn, caption(tidy),
                 heading=comparison_heading([r for *_, r in cols]))


def comparison_heading(measured) -> str:
    """The comparison's title naming the levels it shows: "Comparison at low (10 %) and high (30 %)
    pruning (paper Table 1)" for a run of 10 % and 30 % — never a level that was not measured."""
    keys = {ratios.key(r) for r in measured}
    shown = [f"{lvl.lower()} ({round(100 * r)} %)" for lvl, r in LEVELS if ratios.key(r) in keys]
    words = shown[0] if len(shown) == 1 else ", ".join(shown[:-1]) + " and " + shown[-1]
    return f"Comparison at {words} pruning (paper Table 1)"


def _no_ablation(ok: pd.DataFrame, grid: list[AblationCell], missing: list[str], ratio: float) -> Missing:
    variants = [a.method for a in grid if a.method != catalog.proposed_method()]
    seen = sorted(set(ok.loc[ok["method"].isin(variants), "ratio"]))
    return Missing(f"no ablation variant measured at {ratios.percent(ratio)} pruning: missing "
                   f"{', '.join(m for m in missing if m in variants)} at {ratios.percent(ratio)}"
                   + (f" (they ran at {', '.join(ratios.percent(r) for r in seen)})" if seen else ""))


def _best_means(tidy: pd.DataFrame) -> dict:
    """(dataset, metric) -> the best mean of its row (higher or lower by the metric's direction)."""
    best = {}
    for (lab, mk), t in tidy.groupby(["label", "metric"]):
        vals = t["mean"].dropna()
        if len(vals):
            best[(lab, mk)] = vals.max() if catalog.higher_is_better(mk) else vals.min()
    return best


@dataclass(frozen=True)
class _AblationText:
    """An ablation cell's text: its mean, bold when the best of its row; in the sections also
    ``(ref.)`` on the reference cell and Δ against it on the others."""

    best: dict
    ref: str | None

    def wide(self, r, digits: int) -> str:
        s = mean_text(r, digits)
        return f"**{s}**" if self.best.get((r["label"], r["metric"])) == r["mean"] else s

    def __call__(self, r, digits: int) -> str:
        s = self.wide(r, digits)
        if r["method"] == self.ref:
            return f"{s} (ref.)"
        return s + (f" ({delta_text(r, digits)})" if self.ref else "")


def _ablation_cells(ok: pd.DataFrame, ratio: float) -> tuple[list[AblationCell], list[AblationCell], list[str]]:
    """(the grid's cells, those measured at ``ratio``, the methods of the others)."""
    grid = catalog.ablation_cells()
    at = ok[ok["rkey"] == ratios.key(ratio)]
    present = [a for a in grid if not at[at["method"] == a.method].empty]
    return grid, present, [a.method for a in grid if a not in present]


def table_ablation(df: pd.DataFrame, ratio: float = ABLATION_RATIO):
    ok, mets = prepare(df)
    grid, present, missing = _ablation_cells(ok, ratio)
    full = catalog.proposed_method()
    if all(a.method == full for a in present):  # the full method alone is no ablation
        return _no_ablation(ok, grid, missing, ratio)
    ref = full if full in [a.method for a in present] else None
    cell_of = {a.method: a for a in present}
    spec = CellTable("ablation", [(a.method, "default", ratio) for a in present],
                     lambda c: (ref, "default", ratio) if ref else None, (["Dataset"], ["label"]),
                     lambda r: cell_of[r["method"]].heading, lambda t: [a.heading for a in present])
    tidy = spec.tidy(ok, mets)
    text = _AblationText(_best_means(tidy), ref)
    secs = spec.sections(tidy, mets, text)
    wide_cols = pd.MultiIndex.from_tuples([a.column for a in present], names=["descriptors", "beta"])
    disp = wide(tidy, mets, wide_cols, lambda r: cell_of[r["method"]].column, text.wide)
    notes = notes_for(tidy, catalog.method_label(ref) if ref else "–")
    warn = [f"ablation: missing {', '.join(missing)} at {ratios.percent(ratio)}"] if missing else []
    return Table(disp, notes + [f"not measured: {', '.join(missing)}"] * bool(missing), tidy, secs, warn,
                 caption(tidy, interval=ref is not None))


def _verdict_counts(tidy: pd.DataFrame) -> dict:
    """(row, prune, metric) -> ``better / worse / unclear``: on how many scenes the CI lies above,
    below or across 0."""
    out = {}
    for (row, pr, mk), t in tidy[tidy["scene"] != POOLED].groupby(["row", "prune", "metric"]):
        c = t["verdict"].value_counts()
        out[(row, pr, mk)] = f"{c.get('better', 0)} / {c.get('worse', 0)} / {c.get('unclear', 0)}"
    return out


def table_versus(df: pd.DataFrame, reference: str | None = None):
    reference = reference or catalog.DEFAULT_REFERENCE
    ok, mets = prepare(df)
    refs = set(ok.loc[(ok["method"] == reference) & (ok["variant"] == "default"), "rkey"])
    if not refs:
        return Missing(f"reference method {reference} (default variant) was not measured")
    cells = [(m, v, r) for m in catalog.method_order(ok["method"]) if m != reference
             for v in dict.fromkeys(ok.loc[ok["method"] == m, "variant"])
             for r in sorted(set(ok.loc[(ok["method"] == m) & (ok["variant"] == v), "rkey"]) & refs)]
    if not cells:
        return Missing(f"no method was measured at a ratio where {reference} was")
    spec = CellTable(
        "versus", cells, lambda c: (reference, "default", c[2]), (["Method", "Prune"], ["row", "prune"]),
        lambda r: r["label"], lambda t: [*dict.fromkeys(t.loc[t["scene"] != POOLED, "label"]), "all scenes"],
        pooled=True, extra={
            "row": lambda t: [f"{lab}{'' if v == 'default' else f' [{v}]'}"
                              for lab, v in zip(t["method_label"], t["variant"])],
            "prune": lambda t: [ratios.percent(r) for r in t["ratio"]]})
    tidy = spec.tidy(ok, mets)
    verdicts = _verdict_counts(tidy)
    secs = spec.sections(tidy, mets, _delta_only)
    for (h, t), (mk, *_) in zip(secs, mets):
        t["better / worse / unclear"] = [verdicts.get((*k, mk), "") for k in t.index]
    disp = pd.concat({h: t for h, t in secs}, names=["Metric"])
    notes = [f"Δ = mean paired per-view difference against {catalog.method_label(reference)} at the same ratio "
             "[CI]; all scenes: Δ pooled over the scenes (random effects, HKSJ interval); better/worse = scenes "
             "whose CI excludes 0 in the metric's good/bad direction",
             f"{NEAR}: some pairs left out as near-identical (PSNR ≥ {stats.NEAR_IDENTICAL_DB:g} dB or inf)"]
    return Table(disp, notes, spec.csv(tidy), secs, caption=caption(tidy))


def table_per_scene(df: pd.DataFrame):
    pair = catalog.descriptor_pair()
    if pair is None:
        return Missing("no registered pair of betadesc with and without descriptors")
    without, full = pair
    ok, mets = prepare(df)
    cells = [(full, "default", ratios.from_keep(k)) for k in KEEPS]
    have = [c for c in cells if not ok[(ok["method"] == full) & (ok["rkey"] == ratios.key(c[2]))].empty
            and not ok[(ok["method"] == without) & (ok["rkey"] == ratios.key(c[2]))].empty]
    if not have:
        return Missing(f"needs {full} and {without} at the same keep fraction (0.7 / 0.5 / 0.3)")
    spec = CellTable("per_scene", have, lambda c: (without, "default", c[2]), (["scene"], ["label"]),
                     lambda r: r["prune"], lambda t: list(dict.fromkeys(t["prune"])), pooled=True,
                     extra={"prune": lambda t: ["prune " + ratios.percent(r) for r in t["ratio"]]})
    tidy = spec.tidy(ok, mets)
    secs = spec.sections(tidy, mets, _delta_only)
    disp = pd.concat({h: t for h, t in secs}, names=["Metric"])
    return Table(disp, [f"descriptor gain {full} − {without}, paired per view [CI]; positive "
                        "= descriptors raise the metric"], spec.csv(tidy), secs, caption=caption(tidy))
