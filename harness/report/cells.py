"""Tables whose cells compare a method with a reference row, view by view (:mod:`harness.report.stats`).

Every cell is computed from the per-view results (``status == ok``) of one (scene, method, variant,
ratio): the mean over its views (frames pooled), the median, the number of views and of
near-identical views, and — against its reference row, the same scene and views — the mean paired
difference Δ = cell − reference with its 95 % interval (:func:`harness.report.stats.mean_ci`). The metrics are every
registered metric the results carry (:func:`harness.report.catalog.display_metrics`: OM variants beside full-frame).

* ``comparison`` (paper Table 1): each comparison-group method's default variant at Low/Mid/High =
  10/20/30 % pruning; reference: ``random`` (:data:`catalog.DEFAULT_REFERENCE`, or ``--reference``)
  at the same ratio.
* ``ablation`` (paper Table 2): the descriptors × Beta grid at 20 %; reference: the full method
  (``betadesc``) at 20 %, so Δ < 0 in the higher-is-better sense means the removed part helped.
  Bold: the best mean of a row.
* ``versus``: every measured (method, variant, ratio) against the reference method at the same
  ratio, per scene and pooled over scenes (the random-effects mean of the scene means with its HKSJ
  interval, near-identical pairs left out), with a verdict per row: on how many scenes the CI lies
  above / below 0.
* ``per_scene``: the descriptor gain betadesc − betadesc-nodesc at keep 0.7/0.5/0.3 per scene
  (positive = descriptors help; the paper's "+4.04 dB" sense), paired per view.

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

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.report import catalog, stats
from harness.report.tabledata import Missing, Table

LEVELS = (("Low", 0.1), ("Mid", 0.2), ("High", 0.3))
ABLATION_RATIO = 0.2
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


def cell_rows(ok, mets, cells, reference_of, table: str, pooled: bool = False, levels=None) -> pd.DataFrame:
    """Tidy rows of ``cells`` [(method, variant, ratio)] per scene (and pooled), each against
    ``reference_of(cell)`` (a cell, or None)."""
    groups = {k: g for k, g in ok.groupby(["scene", "method", "variant", "rkey"], sort=False)}
    arrays: dict = {}  # group key -> {metric: (values, near)}, converted once for every cell that reads it

    def cols(key):
        if key not in arrays:
            arrays[key] = {mk: stats.columns(groups[key], mk) for mk, *_ in mets}
        return arrays[key]

    labels = dict(zip(ok["scene"], ok["label"]))
    levels = levels or {}
    out = []
    for cell in cells:
        m, v, r = _key(*cell)
        ref = reference_of(cell)
        rk = _key(*ref) if ref is not None else None
        diffs = {mk: [] for mk, *_ in mets}
        pooled_vals = {mk: [] for mk, *_ in mets}
        for scene in labels:
            g = groups.get((scene, m, v, r))
            if g is None:
                continue
            gr = groups.get((scene, *rk)) if rk and rk != (m, v, r) else None
            pairs = stats.pair_index(g, gr) if gr is not None else None
            size = _size(g)
            here, there = cols((scene, m, v, r)), (cols((scene, *rk)) if gr is not None else None)
            for mk, _, _ in mets:
                row = {"table": table, "scene": scene, "label": labels[scene], "method": m,
                       "method_label": catalog.method_label(m), "variant": v, "ratio": r,
                       "level": levels.get(r, ""), "metric": mk,
                       **stats.summary(*here[mk], mk), **size,
                       "reference": "" if rk is None else f"{rk[0]}[{rk[1]}]"}
                pooled_vals[mk].append(here[mk])
                if gr is not None:
                    d, excl = stats.paired_diffs_at(here[mk], there[mk], mk, pairs)
                    diffs[mk].append((d, excl))
                    row.update(_delta(d, excl, mk))
                out.append(row)
        if pooled and any(diffs.values()):
            for mk, _, _ in mets:
                if not diffs[mk]:
                    continue
                vals = np.concatenate([x for x, _ in pooled_vals[mk]])
                near = np.concatenate([n for _, n in pooled_vals[mk]])
                out.append({"table": table, "scene": POOLED, "label": "all scenes", "method": m,
                            "method_label": catalog.method_label(m), "variant": v, "ratio": r,
                            "level": levels.get(r, ""), "metric": mk, **stats.summary(vals, near, mk),
                            "reference": f"{rk[0]}[{rk[1]}]", **_pooled_delta(diffs[mk], mk)})
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


# --------------------------------------------------------------------------- tables
def table_comparison(df: pd.DataFrame, reference: str | None = None):
    reference = reference or catalog.DEFAULT_REFERENCE
    ok, mets = prepare(df)
    cols = [(grp, m, lvl, r) for grp, m in catalog.comparison_methods(ok["method"]) for lvl, r in LEVELS
            if not ok[(ok["method"] == m) & (ok["variant"] == "default") & (ok["rkey"] == ratios.key(r))].empty]
    if not cols:
        return Missing("no method of the comparison groups was measured at 10/20/30 % pruning")
    levels = {ratios.key(r): f"{lvl} ({ratios.percent(r)})" for lvl, r in LEVELS}
    tidy = cell_rows(ok, mets, [(m, "default", r) for *_, m, _, r in cols], lambda c: (reference, "default", c[2]),
                     "comparison", levels=levels)
    layout = ((["Dataset", "Method"], ["label", "method_label"]), lambda r: r["level"],
              [levels[ratios.key(r)] for _, r in LEVELS if ratios.key(r) in set(tidy["ratio"])])
    secs = _sections(tidy, mets, *layout, lambda r, dg: cell_text(r, dg, r["method"] == reference))
    secs += _size_section(tidy, *layout)
    wide_cols = pd.MultiIndex.from_tuples([(g, catalog.method_label(m), lvl) for g, m, lvl, _ in cols],
                                          names=["group", "method", "level"])
    sizes = [("splats", "splats", 0), ("bytes", "bytes", 0)] if secs[-1][0] == SIZE_HEADING else []
    rows = [(lab, h) for lab in dict.fromkeys(tidy["label"]) for _, h, _ in [*mets, *sizes]]
    disp = pd.DataFrame("–", pd.MultiIndex.from_tuples(rows, names=["Dataset", "Metric"]), wide_cols)
    for (mk, h, dg) in mets:
        for _, r in tidy[tidy["metric"] == mk].iterrows():
            col = next(
                c for c, (_, m, _, rr) in zip(wide_cols, cols) if m == r["method"] and ratios.key(rr) == r["ratio"]
            )
            disp.loc[(r["label"], h), col] = mean_text(r, dg)
            if mk == mets[0][0]:
                for key, h2, _ in sizes:
                    disp.loc[(r["label"], h2), col] = fmt(r[key], 0) if pd.notna(r[key]) else "–"
    warn = [] if reference in set(ok["method"]) else \
        [f"comparison: reference method {reference} not measured; cells show means without Δ"]
    return Table(disp, notes_for(tidy, catalog.method_label(reference)), tidy, secs, warn, caption(tidy))


def table_ablation(df: pd.DataFrame, ratio: float = ABLATION_RATIO):
    ok, mets = prepare(df)
    grid = catalog.ablation_cells()
    at = ok[ok["rkey"] == ratios.key(ratio)]
    present = [a for a in grid if not at[at["method"] == a[2]].empty]
    missing = [a[2] for a in grid if a not in present]
    variants = [a[2] for a in grid if a[2] != catalog.proposed_method()]
    if not [a for a in present if a[2] in variants]:  # the full method alone is no ablation
        seen = sorted(set(ok.loc[ok["method"].isin(variants), "ratio"]))
        return Missing(f"no ablation variant measured at {ratios.percent(ratio)} pruning: missing "
                       f"{', '.join(m for m in missing if m in variants)} at {ratios.percent(ratio)}"
                       + (f" (they ran at {', '.join(ratios.percent(r) for r in seen)})" if seen else ""))
    full = catalog.proposed_method()
    ref = full if full in [a[2] for a in present] else None
    tidy = cell_rows(ok, mets, [(a[2], "default", ratio) for a in present],
                     lambda c: (ref, "default", ratio) if ref else None, "ablation")
    heads = {a[2]: f"{a[0]} · {a[1]}" for a in present}
    best = {}
    for (lab, mk), t in tidy.groupby(["label", "metric"]):
        vals = t["mean"].dropna()
        if len(vals):
            best[(lab, mk)] = vals.max() if catalog.higher_is_better(mk) else vals.min()

    def text(r, dg, wide=False):
        s = mean_text(r, dg)
        if best.get((r["label"], r["metric"])) == r["mean"]:
            s = f"**{s}**"
        return s if wide else (f"{s} (ref.)" if r["method"] == ref else s + (f" ({delta_text(r, dg)})" if ref else ""))

    secs = _sections(tidy, mets, (["Dataset"], ["label"]), lambda r: heads[r["method"]],
                     [heads[a[2]] for a in present], text)
    wide_cols = pd.MultiIndex.from_tuples([a[:2] for a in present], names=["descriptors", "beta"])
    rows = [(lab, h) for lab in dict.fromkeys(tidy["label"]) for _, h, _ in mets]
    disp = pd.DataFrame("–", pd.MultiIndex.from_tuples(rows, names=["Dataset", "Metric"]), wide_cols)
    for mk, h, dg in mets:
        for _, r in tidy[tidy["metric"] == mk].iterrows():
            a = next(a for a in present if a[2] == r["method"])
            disp.loc[(r["label"], h), a[:2]] = text(r, dg, wide=True)
    notes = notes_for(tidy, catalog.method_label(ref) if ref else "–")
    warn = [f"ablation: missing {', '.join(missing)} at {ratios.percent(ratio)}"] if missing else []
    return Table(disp, notes + [f"not measured: {', '.join(missing)}"] * bool(missing), tidy, secs, warn,
                 caption(tidy, interval=ref is not None))


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
    tidy = cell_rows(ok, mets, cells, lambda c: (reference, "default", c[2]), "versus", pooled=True)
    scenes = [*dict.fromkeys(tidy.loc[tidy["scene"] != POOLED, "label"]), "all scenes"]
    tidy["row"] = [
        f"{lab}{'' if v == 'default' else f' [{v}]'}" for lab, v in zip(tidy["method_label"], tidy["variant"])
    ]
    tidy["prune"] = [ratios.percent(r) for r in tidy["ratio"]]
    verdicts = {}
    for (row, pr, mk), t in tidy[tidy["scene"] != POOLED].groupby(["row", "prune", "metric"]):
        c = t["verdict"].value_counts()
        verdicts[(row, pr, mk)] = f"{c.get('better', 0)} / {c.get('worse', 0)} / {c.get('unclear', 0)}"
    secs = _sections(tidy, mets, (["Method", "Prune"], ["row", "prune"]), lambda r: r["label"], scenes,
                     lambda r, dg: delta_text(r, dg).removeprefix("Δ ") + (NEAR if r["n_pairs_excluded"] else ""))
    for (h, t), (mk, *_) in zip(secs, mets):
        t["better / worse / unclear"] = [verdicts.get((*k, mk), "") for k in t.index]
    disp = pd.concat({h: t for h, t in secs}, names=["Metric"])
    notes = [f"Δ = mean paired per-view difference against {catalog.method_label(reference)} at the same ratio "
             "[CI]; all scenes: Δ pooled over the scenes (random effects, HKSJ interval); better/worse = scenes "
             "whose CI excludes 0 in the metric's good/bad direction",
             f"{NEAR}: some pairs left out as near-identical (PSNR ≥ {stats.NEAR_IDENTICAL_DB:g} dB or inf)"]
    return Table(disp, notes, tidy.drop(columns=["row", "prune"]), secs, caption=caption(tidy))


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
    tidy = cell_rows(ok, mets, have, lambda c: (without, "default", c[2]), "per_scene", pooled=True)
    tidy["prune"] = ["prune " + ratios.percent(r) for r in tidy["ratio"]]
    cols = list(dict.fromkeys(tidy["prune"]))
    secs = _sections(tidy, mets, (["scene"], ["label"]), lambda r: r["prune"], cols,
                     lambda r, dg: delta_text(r, dg).removeprefix("Δ ") + (NEAR if r["n_pairs_excluded"] else ""))
    disp = pd.concat({h: t for h, t in secs}, names=["Metric"])
    return Table(disp, [f"descriptor gain {full} − {without}, paired per view [CI]; positive "
                        "= descriptors raise the metric"], tidy.drop(columns=["prune"]), secs, caption=caption(tidy))
