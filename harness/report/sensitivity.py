"""The robustness tables of the paper's §4.4, per scene with paired intervals: keep fractions (Table 3)
and the sensitivity sweeps (coefficient presets, voxel sizes).

Both are built by :func:`harness.report.cells.cell_rows` — per scene, the mean over held-out views
and the mean paired per-view difference Δ against a reference cell with its 95 % interval
(:func:`harness.report.stats.mean_ci`), plus the pooled row ``all scenes`` (Δ pooled over the scenes
by random effects with its HKSJ interval, as every table does; the means over all their views):

* ``keep`` (Table 3): ``betadesc-nodesc`` and ``betadesc`` at keep 0.7 / 0.5 / 0.3 (prune
  30 / 50 / 70 %); Δ = no descriptors − with descriptors (the paper's ΔPSNR sign: negative when
  descriptors help), paired per view.
* ``sensitivity``: ``betadesc`` variants at keep 0.7 — coefficient presets and voxel sizes (variants
  named ``preset=…`` / ``voxel=…``), each against the default variant at the same scene and views;
  per scene the PSNR spread across the variants measured there.

Tidy columns: those of :data:`harness.report.cells.TIDY`, plus ``knob`` for the sensitivity table.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.report import catalog, cells, stats
from harness.report.tabledata import Missing, Table

KEEPS = cells.KEEPS
#: the paper's sensitivity knobs: swept parameter -> row group
SENSITIVITY_KNOBS = {"preset": "coefficients (presets other than baseline: ours)", "voxel": "voxel size"}


def _text(r, digits: int, ref: bool) -> str:
    return cells.cell_text(r, digits, ref)


def _layout(tidy: pd.DataFrame, mets, row_of, col_of, cols, text) -> tuple[list, pd.DataFrame]:
    """One section per metric (rows: ``row_of(r)``, columns ``cols``) and their stack (the .tex)."""
    secs = []
    for mk, heading, digits in mets:
        t = tidy[tidy["metric"] == mk]
        if t.empty:
            continue
        rows = list(dict.fromkeys(row_of(r) for _, r in t.iterrows()))
        table = pd.DataFrame("–", pd.MultiIndex.from_tuples(rows), cols)
        for _, r in t.iterrows():
            table.loc[row_of(r), col_of(r)] = text(r, digits)
        secs.append((heading, table))
    return secs, pd.concat({h: t for h, t in secs}, names=["Metric"])


def table_keep(df: pd.DataFrame):
    pair = catalog.descriptor_pair()
    if pair is None:
        return Missing("no registered pair of betadesc with and without descriptors")
    without, full = pair
    ok, mets = cells.prepare(df)
    have = [r for r in (ratios.from_keep(k) for k in KEEPS)
            if all(not ok[(ok["method"] == m) & (ok["variant"] == "default") & (ok["rkey"] == ratios.key(r))].empty
                   for m in pair)]
    if not have:
        return Missing(f"needs {without} and {full} at keep {' / '.join(f'{k:g}' for k in KEEPS)} "
                       "on a common scene; neither was measured at those keep fractions")
    # only the (scene, keep) pairs both sides were measured at: pooled means compare the same images
    both = ok[ok["method"].isin(pair) & (ok["variant"] == "default")].groupby(["scene", "rkey"])["method"].nunique()
    ok = ok.set_index(["scene", "rkey"]).loc[lambda d: d.index.isin(both[both == 2].index)].reset_index()
    cell_list = [(m, "default", r) for r in have for m in (without, full)]
    # each side paired with the other (so both get pooled rows); Δ is kept on the no-descriptor side only
    tidy = cells.cell_rows(ok, mets, cell_list, lambda c: (full if c[0] == without else without, "default", c[2]),
                           "keep", pooled=True)
    own = tidy["method"] == full
    tidy.loc[own, "reference"] = ""
    tidy.loc[own, ["delta", "ci_low", "ci_high", "delta_median", "n_pairs", "n_pairs_excluded", "verdict"]] = np.nan
    side = {without: "No Descriptors", full: "With Descriptors"}
    tidy["prune"] = [ratios.percent(r) for r in tidy["ratio"]]

    def row_of(r):
        return (r["label"], r["prune"])

    def text(r, dg):
        return cells.mean_text(r, dg) + (f" ({cells.delta_text(r, dg)})" if r["method"] == without else "")

    secs, disp = _layout(tidy, mets, row_of, lambda r: side[r["method"]], list(side.values()), text)
    for _, t in secs:  # rows in cell_rows' order: scenes as measured, pooled last
        t.index = t.index.set_names(["scene", "Prune %"])
    notes = [f"Δ = {catalog.method_label(without)} − {catalog.method_label(full)} at the same scene, keep and views "
             "(the paper's ΔPSNR sign: negative when descriptors help); all scenes: Δ pooled over the scenes (random "
             "effects, HKSJ interval)",
             stats.interval_note(tidy.loc[tidy["scene"] != cells.POOLED, "n_pairs"].dropna())]
    keeps = " / ".join(f"{1 - r:g}" for r in have)
    return Table(disp, notes, tidy.drop(columns=["prune"]).reset_index(drop=True), secs,
                 heading=f"Keep fraction{'s' if len(have) > 1 else ''} {keeps} with and without descriptors "
                         "(paper Table 3)")


def _knob(variant: str) -> str | None:
    """The swept parameter of a sweep variant named ``<param>=<value>``."""
    return next((k for k in SENSITIVITY_KNOBS if variant.startswith(f"{k}=")), None)


def table_sensitivity(df: pd.DataFrame, keep: float = 0.7):
    method = catalog.proposed_method()
    r = ratios.from_keep(keep)
    ok, mets = cells.prepare(df)
    at = ok[(ok["method"] == method) & (ok["rkey"] == ratios.key(r))]
    variants = [v for v in dict.fromkeys(at["variant"]) if v == "default" or _knob(v)]
    if len(variants) < 2:
        return Missing(f"needs {method}'s default variant and at least one sweep variant "
                       f"({' / '.join(f'{k}=…' for k in SENSITIVITY_KNOBS)}) at keep {keep:g}; found "
                       f"{', '.join(variants) or 'none'}")
    order = list(SENSITIVITY_KNOBS)
    variants = sorted(variants, key=lambda v: (v != "default", order.index(_knob(v)) if _knob(v) else -1))
    swept = set(at.loc[at["variant"] != "default", "scene"])  # scenes some sweep variant ran on
    ok = ok[ok["scene"].isin(swept)]
    tidy = cells.cell_rows(ok, mets, [(method, v, r) for v in variants], lambda c: (method, "default", r),
                           "sensitivity", pooled=True)
    tidy.insert(1, "knob", ["baseline" if v == "default" else SENSITIVITY_KNOBS[_knob(v)] for v in tidy["variant"]])
    scenes = [*dict.fromkeys(tidy.loc[tidy["scene"] != cells.POOLED, "label"]), "all scenes"]
    secs, disp = _layout(tidy, mets, lambda x: (x["knob"], x["variant"]), lambda x: x["label"], scenes,
                         lambda x, dg: _text(x, dg, x["variant"] == "default"))
    for _, t in secs:
        t.index = t.index.set_names(["knob", "variant"])
    notes = [f"{method} at keep {keep:g}; Δ = variant − the default variant at the same scene and views; all "
             "scenes: Δ pooled over the scenes the variant was measured on (random effects, HKSJ interval)",
             stats.interval_note(tidy.loc[(tidy["scene"] != cells.POOLED) & (tidy["variant"] != "default"),
                                          "n_pairs"].dropna()),
             "the paper gives values only for the baseline preset; flat, opacity-heavy and structure-heavy are "
             "this project's own coefficients"]
    return Table(disp, notes + _psnr_spread(tidy), tidy.reset_index(drop=True), secs)


def _psnr_spread(tidy: pd.DataFrame) -> list[str]:
    """The note of the PSNR spread across the variants, per scene (none without PSNR rows)."""
    psnr = tidy[(tidy["metric"] == "psnr") & (tidy["scene"] != cells.POOLED)]
    if not len(psnr):
        return []
    spread = psnr.groupby("label", sort=False)["mean"].agg(lambda m: np.nanmax(m) - np.nanmin(m)
                                                            if np.isfinite(m).any() else np.nan)
    return ["PSNR spread across the variants, per scene: " + ", ".join(
        f"{lab} {v:.2f} dB" for lab, v in spread.items() if np.isfinite(v))]
