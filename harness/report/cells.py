"""Cells that compare a method with a reference row, view by view (:mod:`harness.report.stats`), and
the declared tables made of them (:class:`CellTable`; the tables: :mod:`harness.report.cell_tables`).

Every cell is computed from the per-view results (``status == ok``) of one (scene, method, variant,
ratio): the mean over its views (frames pooled), the median, the number of views and of
near-identical views, and — against its reference row, the same scene and views — the mean paired
difference Δ = cell − reference with its 95 % interval (:func:`harness.report.stats.mean_ci`). The metrics are every
registered metric the results carry (:func:`harness.report.catalog.display_metrics`: OM variants beside full-frame).

Tidy columns (one row per scene × method × variant × ratio × metric): ``table, scene, label, method,
method_label, variant, ratio, level, metric, mean, std, median, n, n_near_identical, splats, bytes,
reference, delta, ci_low, ci_high, delta_median, n_pairs, n_pairs_excluded, verdict`` —
``std`` is the sample standard deviation (ddof = 1) of the values the mean is taken over,
``splats``/``bytes`` the kept splats and the pruned ``.ply`` size (means over frames),
``ci_low/ci_high`` bound Δ (:data:`harness.report.stats.INTERVAL_DESCRIPTION`). Pooled rows have
``scene = "*"`` (and no splats or bytes: those are per scene).

Every table's ``caption`` (:func:`caption`) gives ``n`` — views per cell, and for pooled rows pairs
over how many scenes — and the interval method.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.report import catalog, stats

KEEPS = (0.7, 0.5, 0.3)
NEAR = "‡"
POOLED = "*"


def prepare(df: pd.DataFrame):
    """(measured rows with a ``near`` flag and a ratio key, [(metric, heading, digits)] shown)."""
    ok = df[df["status"] == "ok"].copy()
    mets = [m for m in catalog.display_metrics(ok.columns) if ok[m[0]].notna().any()]
    ok["near"] = stats.near_identical(ok, [m[0] for m in mets])
    ok["rkey"] = ok["ratio"].round(ratios.DECIMALS)
    return ok, mets


def _key(method, variant, ratio):
    return method, variant, ratios.key(ratio)


class _Groups:
    """The measured rows of every (scene, method, variant, ratio), and their metric columns converted
    once for every cell that reads them (:func:`harness.report.stats.columns`)."""

    def __init__(self, ok: pd.DataFrame, mets):
        self.rows = {k: g for k, g in ok.groupby(["scene", "method", "variant", "rkey"], sort=False)}
        self.mets, self._columns = mets, {}

    def columns(self, key) -> dict:
        if key not in self._columns:
            self._columns[key] = {mk: stats.columns(self.rows[key], mk) for mk, *_ in self.mets}
        return self._columns[key]


class _Pool:
    """One cell's values and paired differences over its scenes, per metric: its pooled row."""

    def __init__(self, mets):
        self.values = {mk: [] for mk, *_ in mets}
        self.diffs = {mk: [] for mk, *_ in mets}

    def rows(self, base: dict, ref: str) -> list[dict]:
        if not any(self.diffs.values()):
            return []
        out = []
        for mk, values in self.values.items():
            if not self.diffs[mk]:
                continue
            vals, near = np.concatenate([x for x, _ in values]), np.concatenate([n for _, n in values])
            out.append({**base, "scene": POOLED, "label": "all scenes", "metric": mk, **stats.summary(vals, near, mk),
                        "reference": ref, **_pooled_delta(self.diffs[mk], mk)})
        return out


def _scene_rows(groups: _Groups, scene: str, key, rk, base: dict, pool: _Pool) -> list[dict]:
    """The rows of cell ``key`` at one scene, one per metric, Δ against ``rk`` where it was measured."""
    g = groups.rows.get((scene, *key))
    if g is None:
        return []
    gr = groups.rows.get((scene, *rk)) if rk and rk != key else None
    pairs = stats.pair_index(g, gr) if gr is not None else None
    here, there = groups.columns((scene, *key)), (groups.columns((scene, *rk)) if gr is not None else None)
    size, out = _size(g), []
    for mk, _, _ in groups.mets:
        row = {**base, "scene": scene, "metric": mk, **stats.summary(*here[mk], mk), **size}
        pool.values[mk].append(here[mk])
        if gr is not None:
            d, excl = stats.paired_diffs_at(here[mk], there[mk], mk, pairs)
            pool.diffs[mk].append((d, excl))
            row.update(_delta(d, excl, mk))
        out.append(row)
    return out


def cell_rows(ok, mets, cells, reference_of, table: str, pooled: bool = False, levels=None) -> pd.DataFrame:
    """Tidy rows of ``cells`` [(method, variant, ratio)] per scene (and pooled), each against
    ``reference_of(cell)`` (a cell, or None)."""
    groups = _Groups(ok, mets)
    labels = dict(zip(ok["scene"], ok["label"]))
    out = []
    for cell in cells:
        key, ref = _key(*cell), reference_of(cell)
        rk = _key(*ref) if ref is not None else None
        base = {"table": table, "method": key[0], "method_label": catalog.method_label(key[0]), "variant": key[1],
                "ratio": key[2], "level": (levels or {}).get(key[2], ""),
                "reference": "" if rk is None else f"{rk[0]}[{rk[1]}]"}
        pool = _Pool(mets)
        for scene, label in labels.items():
            out += [{**row, "label": label} for row in _scene_rows(groups, scene, key, rk, base, pool)]
        if pooled:
            out += pool.rows(base, base["reference"])
    tidy = pd.DataFrame(out, columns=TIDY)
    rank = {s: i for i, s in enumerate([*labels, POOLED])}  # scenes in results order, pooled last; cells as given
    return tidy.iloc[np.argsort(tidy["scene"].map(rank).to_numpy(), kind="stable")].reset_index(drop=True)


TIDY = ["table", "scene", "label", "method", "method_label", "variant", "ratio", "level", "metric", "mean", "std",
        "median", "n", "n_near_identical", "splats", "bytes", "reference", "delta", "ci_low", "ci_high",
        "delta_median", "n_pairs", "n_pairs_excluded", "verdict"]


def _size(g: pd.DataFrame) -> dict:
    """Kept splats and pruned .ply bytes of one cell: the mean over its frames (one value per frame,
    repeated on each of its view rows)."""
    out = {}
    for col, key in (("splats_out", "splats"), ("bytes", "bytes")):
        per_frame = pd.to_numeric(g[col], errors="coerce").groupby(g["frame"]).first() if col in g else None
        out[key] = float(per_frame.mean()) if per_frame is not None and per_frame.notna().any() else np.nan
    return out


def caption(tidy: pd.DataFrame, interval: bool = True) -> str:
    """``n`` of a cell table — held-out views per cell, pairs and scenes of the pooled rows — and how
    its intervals are computed (:data:`harness.report.stats.INTERVAL_DESCRIPTION`)."""
    per = tidy[tidy["scene"] != POOLED].drop_duplicates(["scene", "method", "variant", "ratio"])
    parts = []
    if len(per):
        lo, hi = int(per["n"].min()), int(per["n"].max())
        parts.append(f"n = {lo if lo == hi else f'{lo}–{hi}'} held-out view(s) per cell "
                     f"({per['scene'].nunique()} scene(s))")
    pooled = tidy[tidy["scene"] == POOLED]
    if len(pooled):
        k = per["scene"].nunique()
        lo, hi = int(pooled["n_pairs"].min()), int(pooled["n_pairs"].max())
        parts.append(f"all scenes: n = {lo if lo == hi else f'{lo}–{hi}'} pairs over {k} scene(s); Δ pooled over "
                     "the scenes (random effects, HKSJ 95 % interval over the scene means)")
    if interval:
        parts.append(f"Δ: {stats.INTERVAL_DESCRIPTION}")
    return "; ".join(parts)


def _pooled_delta(per_scene: list[tuple[np.ndarray, int]], metric: str) -> dict:
    """Δ over scenes: the random-effects mean of the per-scene mean differences with its HKSJ 95 %
    interval (:func:`harness.report.meta.pooled`; one scene: its own t interval) — never the views
    of different scenes pooled as one sample."""
    from harness.report import meta

    e = meta.pooled([meta.of_values(d) for d, _ in per_scene])
    lo, hi = e.interval() if e.n else (np.nan, np.nan)
    d = np.concatenate([x for x, _ in per_scene])
    return {"delta": e.mean, "ci_low": lo, "ci_high": hi, "delta_median": float(np.median(d)) if d.size else np.nan,
            "n_pairs": int(d.size), "n_pairs_excluded": int(sum(x for _, x in per_scene)),
            "verdict": stats.verdict(lo, hi, catalog.higher_is_better(metric))}


def _delta(d: np.ndarray, excluded: int, metric: str) -> dict:
    lo, hi = stats.mean_ci(d)
    return {"delta": float(d.mean()) if d.size else np.nan, "ci_low": lo, "ci_high": hi,
            "delta_median": float(np.median(d)) if d.size else np.nan, "n_pairs": int(d.size),
            "n_pairs_excluded": int(excluded), "verdict": stats.verdict(lo, hi, catalog.higher_is_better(metric))}


# --------------------------------------------------------------------------- display
def fmt(v, digits: int, sign: bool = False) -> str:
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return "–"
    if np.isinf(v):
        return "inf" if v > 0 else "-inf"
    return f"{v:+.{digits}f}" if sign else f"{v:.{digits}f}"


def mean_text(r, digits: int) -> str:
    """The cell's mean, ``‡`` when some of its views are near-identical (``inf‡``/``≥100‡`` when all are)."""
    if r["n_near_identical"] and np.isnan(r["mean"]) and stats.is_db(r["metric"]):
        return f"≥{stats.NEAR_IDENTICAL_DB:g}{NEAR}"
    return fmt(r["mean"], digits) + (NEAR if r["n_near_identical"] else "")


def delta_text(r, digits: int) -> str:
    if not r["reference"] or r["reference"] == f"{r['method']}[{r['variant']}]" or pd.isna(r["n_pairs"]):
        return ""  # no reference row measured at this scene and ratio: nothing to compare with
    if pd.isna(r["delta"]):
        return "Δ –"
    ci = "" if pd.isna(r["ci_low"]) else f" [{fmt(r['ci_low'], digits, True)}, {fmt(r['ci_high'], digits, True)}]"
    return f"Δ {fmt(r['delta'], digits, True)}{ci}"


def cell_text(r, digits: int, ref_cell: bool) -> str:
    if ref_cell:
        return f"{mean_text(r, digits)} (ref.)"
    d = delta_text(r, digits)
    return mean_text(r, digits) + (f" ({d})" if d else "")


def notes_for(tidy: pd.DataFrame, reference: str) -> list[str]:
    n_near = int(tidy.drop_duplicates(["scene", "method", "variant", "ratio"])["n_near_identical"].sum())
    out = [f"cells: mean over held-out views (Δ = mean paired per-view difference against {reference} at the "
           "same ratio [CI]; n and the interval: the caption)"]
    if n_near:
        out.append(f"{NEAR}: cell with near-identical views (PSNR ≥ {stats.NEAR_IDENTICAL_DB:g} dB or inf; "
                   f"{n_near} view(s) in all) — left out of dB means and Δ; medians over all views in the .csv")
    return out


def _sections(tidy, mets, row_keys, col_key, col_order, text) -> list[tuple[str, pd.DataFrame]]:
    out = []
    for mk, heading, digits in mets:
        t = tidy[tidy["metric"] == mk]
        if t.empty:
            continue
        rows = list(dict.fromkeys(tuple(x) for x in t[row_keys[1]].itertuples(index=False)))
        cols = list(col_order)
        cells = {}  # (row, column) -> text, later rows over earlier ones; filled into the frame at once
        for _, r in t.iterrows():
            cells[(tuple(r[c] for c in row_keys[1]), col_key(r))] = text(r, digits)
        cols += [c for c in dict.fromkeys(c for _, c in cells) if c not in cols]
        at_row, at_col = {k: i for i, k in enumerate(rows)}, {c: j for j, c in enumerate(cols)}
        grid = np.full((len(rows), len(cols)), "–", dtype=object)
        for (rk, ck), s in cells.items():
            grid[at_row[rk], at_col[ck]] = s
        index = pd.MultiIndex.from_tuples(rows, names=row_keys[0])
        columns = (col_order.append(pd.Index(cols[len(col_order):])) if isinstance(col_order, pd.Index)
                   else pd.Index(cols, tupleize_cols=False))
        out.append((heading, pd.DataFrame(grid, index, columns)))
    return out


SIZE_HEADING = "Kept splats · pruned .ply size"


def size_text(r) -> str:
    """``12,345 splats · 2.93 MiB`` of one cell (– where the results carry no count or size)."""
    parts = [f"{int(round(r['splats'])):,} splats" if pd.notna(r["splats"]) else "–",
             f"{r['bytes'] / 2**20:.2f} MiB" if pd.notna(r["bytes"]) else "–"]
    return " · ".join(parts)


def _size_section(tidy, row_keys, col_key, col_order) -> list[tuple[str, pd.DataFrame]]:
    """One section of each cell's kept splats and bytes (the rate of a rate point), laid out as the
    metric sections are."""
    first = tidy[(tidy["metric"] == tidy["metric"].iloc[0]) & (tidy["scene"] != POOLED)] if len(tidy) else tidy
    if first.empty or (first["splats"].isna().all() and first["bytes"].isna().all()):
        return []
    return _sections(first.assign(metric="size"), [("size", SIZE_HEADING, 0)], row_keys, col_key, col_order,
                     lambda r, _: size_text(r))


# --------------------------------------------------------------------------- declared tables
@dataclass(frozen=True)
class CellTable:
    """A table of cells, declared: its ``name``; its ``cells`` (method, variant, ratio), each against
    ``reference(cell)`` (a cell, or None), with pooled rows over scenes when ``pooled``; where a cell
    goes in the per-metric sections — rows (index names, the tidy columns that key a row), the column
    of a tidy row, the columns' order (of the tidy rows) — and display columns ``extra`` derived from
    the tidy rows (dropped from the tidy ``.csv``); ``levels``: a ratio's level name (Low/Mid/High)."""

    name: str
    cells: list
    reference: Callable
    rows: tuple[list[str], list[str]]
    column: Callable
    order: Callable
    pooled: bool = False
    levels: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)

    def tidy(self, ok: pd.DataFrame, mets) -> pd.DataFrame:
        tidy = cell_rows(ok, mets, self.cells, self.reference, self.name, self.pooled, self.levels)
        for name, of in self.extra.items():
            tidy[name] = of(tidy)
        return tidy

    def sections(self, tidy: pd.DataFrame, mets, text) -> list[tuple[str, pd.DataFrame]]:
        """One section per metric, each cell's ``text(row, digits)``."""
        return _sections(tidy, mets, self.rows, self.column, self.order(tidy), text)

    def size_section(self, tidy: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
        return _size_section(tidy, self.rows, self.column, self.order(tidy))

    def csv(self, tidy: pd.DataFrame) -> pd.DataFrame:
        return tidy.drop(columns=list(self.extra))


def wide(tidy, mets, columns: pd.MultiIndex, column_of, text, sizes=()) -> pd.DataFrame:
    """The paper's wide layout: a row per (dataset, metric) and per size row, a column per cell
    (``column_of(row)``), each cell's ``text(row, digits)``; sizes come with the first metric's rows."""
    rows = [(lab, h) for lab in dict.fromkeys(tidy["label"]) for _, h, _ in [*mets, *sizes]]
    disp = pd.DataFrame("–", pd.MultiIndex.from_tuples(rows, names=["Dataset", "Metric"]), columns)
    for mk, h, dg in mets:
        for _, r in tidy[tidy["metric"] == mk].iterrows():
            col = column_of(r)
            disp.loc[(r["label"], h), col] = text(r, dg)
            for key, h2, _ in sizes if mk == mets[0][0] else ():
                disp.loc[(r["label"], h2), col] = fmt(r[key], 0) if pd.notna(r[key]) else "–"
    return disp
