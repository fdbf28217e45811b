"""The paper's tables from tidy results (pandas), as markdown, tidy csv and LaTeX.

Each builder returns a :class:`harness.report.tabledata.Table` — or a
:class:`~harness.report.tabledata.Missing` saying why it cannot be made from these results (which
variants or ratios are missing); ``write_tables`` writes ``tables/<name>.md`` (one small table per
group), ``.csv`` (long format, one header row) and ``.tex`` (the paper's wide layout) and reports the
missing ones (their stale files are removed). Only ``status == ok`` rows enter.

Which methods go where is asked of the pruner registry (:mod:`harness.report.catalog`): labels,
comparison groups, each method's cell of the paper's ablation grid; which metrics, of the metric
registry (every registered metric the results carry).

* ``comparison``, ``ablation``, ``versus``, ``per_scene``: cells with per-view paired differences and
  bootstrap CIs, :mod:`harness.report.cells`.
* ``keep`` (Table 3): keep 0.7/0.5/0.3 (prune 30/50/70 %), pooled over scenes, betadesc-nodesc
  vs betadesc, and ΔPSNR = PSNR(no descriptors) − PSNR(with descriptors) — the paper's sign
  (negative when descriptors help). PSNR means exclude +inf pairs (counted in a note).
* ``sensitivity``: betadesc variants at keep 0.7 — coefficient presets and voxel sizes (variants
  named ``preset=…`` / ``voxel=…``; the default variant is the baseline row).
* ``runtime``: scoring seconds per scene of every method's default variant, with the descriptor
  overhead betadesc − betadesc-nodesc in seconds and in % of betadesc-nodesc's time — "–" when that
  time is under :data:`MIN_BASE_S` (a percentage of timer noise means nothing).
* ``bd`` and ``ctc``: rate points, BD-rate / BD-PSNR against the config's anchor, and the CTC's
  per-sequence CSV layout (:mod:`harness.report.bd`).
"""

from __future__ import annotations

import dataclasses
import inspect
from pathlib import Path

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.io.files import atomic_write_text
from harness.report import bd, catalog, cells
from harness.report.summary import PROTOCOL_NOTES, protocol_subsets, summarise
from harness.report.tabledata import Built, Missing, Table, Written, as_table

KEEPS = cells.KEEPS
#: the runtime table's overhead percentage needs at least this many seconds in its denominator
MIN_BASE_S = 1.0
#: the paper's sensitivity knobs (Table 4): swept parameter -> row group
SENSITIVITY_KNOBS = {"preset": "coefficients (presets other than baseline: ours)", "voxel": "voxel size"}


def _at(df: pd.DataFrame, ratio: float) -> pd.Series:
    """Rows of ``df`` at pruning ratio ``ratio``."""
    return (df["ratio"] - ratio).abs() <= ratios.TOLERANCE


def _metrics(s: pd.DataFrame | None = None) -> list[tuple[str, str, int]]:
    """(name, heading, digits) of the metrics to show: the 3DGS set, or every registered metric
    ``s`` has values for (MPEG columns carry the tool's names: RGB-PSNR, YUV-PSNR, YUV-SSIM, OM-…)."""
    if s is None:
        return catalog.metric_columns(("psnr", "ssim", "lpips"))
    return [c for c in catalog.metric_columns(s.columns) if s[c[0]].notna().any()]




def _fmt(v, digits: int) -> str:
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return "–"
    if np.isinf(v):
        return "inf"
    return f"{v:.{digits}f}"


# --------------------------------------------------------------------------- tables
def _pooled(df: pd.DataFrame, method: str, ratio: float, variant: str = "default") -> dict:
    """Means of PSNR (finite views), SSIM and LPIPS over every measured view of a cell pooled over
    scenes, each with its sample standard deviation (``<metric>_std``, ddof = 1), ``n`` and ``n_inf``."""
    ok = df[(df["status"] == "ok") & (df["method"] == method) & (df["variant"] == variant)
            & _at(df, ratio)]
    fin = ok["psnr"][np.isfinite(ok["psnr"])]
    out = {"psnr": fin.mean() if len(fin) else (np.inf if len(ok) else np.nan), "psnr_std": _std(fin),
           "n": len(ok), "n_inf": int(np.isinf(ok["psnr"]).sum())}
    for m in ("ssim", "lpips"):
        out[m], out[f"{m}_std"] = ok[m].mean(), _std(ok[m])
    return out


def _std(values) -> float:
    """Sample standard deviation (ddof = 1) of the non-NaN values; NaN below two values."""
    v = pd.to_numeric(pd.Series(values), errors="coerce").dropna()
    return float(v.std(ddof=1)) if len(v) > 1 else np.nan


def _pooled_tidy(records) -> pd.DataFrame:
    """Tidy rows of pooled cells: [(row keys dict, _pooled dict)] -> one row per metric with
    ``mean, std, n, n_inf``."""
    rows = [{**keys, "metric": m, "mean": p[m], "std": p[f"{m}_std"], "n": p["n"], "n_inf": p["n_inf"]}
            for keys, p in records for m in ("psnr", "ssim", "lpips")]
    return pd.DataFrame(rows)


#: caption of the tables that pool views over scenes without an interval
POOLED_CAPTION = ("n = the views pooled into each mean (the pairs columns); no interval: plain means "
                  "(the .csv has each mean's std)")


def _common(df: pd.DataFrame, cells) -> tuple[pd.DataFrame, list[str]]:
    """Rows of the scenes (and frames) that every (method, variant, ratio) cell was measured on, so
    pooled means compare the methods on the same image pairs; also those scenes' names."""
    ok = df[df["status"] == "ok"]
    sets = []
    for m, v, r in cells:
        c = ok[(ok["method"] == m) & (ok["variant"] == v) & _at(ok, r)]
        if len(c):
            sets.append(set(c["scene"]))
    common = sorted(set.intersection(*sets)) if sets else []
    return df[df["scene"].isin(common)], common


def table_keep(df: pd.DataFrame):
    pair = catalog.descriptor_pair()
    if pair is None:
        return Missing("no registered pair of betadesc with and without descriptors")
    without, full = pair
    rows, idx, records = [], [], []
    for k in KEEPS:
        r = ratios.from_keep(k)
        sub, _ = _common(df, [(without, "default", r), (full, "default", r)])
        a, b = _pooled(sub, without, r), _pooled(sub, full, r)
        if a["n"] == 0 and b["n"] == 0:
            continue
        idx.append(ratios.percent(r))
        rows.append([a["psnr"], a["ssim"], a["lpips"], b["psnr"], b["ssim"], b["lpips"], a["psnr"] - b["psnr"],
                     a["n"], b["n"]])
        records += [({"prune": ratios.percent(r), "ratio": r, "keep": k, "method": m}, p)
                    for m, p in ((without, a), (full, b))]
    if not rows:
        return Missing(f"needs {without} and {full} at keep {' / '.join(f'{k:g}' for k in KEEPS)} "
                       "on a common scene; neither was measured at those keep fractions")
    mi = pd.MultiIndex.from_tuples(
        [("No Descriptors", m) for _, m, _ in _metrics()] + [("With Descriptors", m) for _, m, _ in _metrics()]
        + [("ΔPSNR", "(dB)"), ("pairs", "no desc."), ("pairs", "with desc.")], names=["side", "quantity"])
    num = pd.DataFrame(rows, pd.Index(idx, name="Prune %"), mi)
    digits = [2, 3, 3, 2, 3, 3, 2, 0, 0]
    disp = num.copy().astype(object)
    for j, d in enumerate(digits):
        disp.iloc[:, j] = [(_fmt(v, d) if d else str(int(v))) for v in num.iloc[:, j]]
    notes = ["pooled over every pair of the scenes both were measured on; "
             "ΔPSNR = no-desc − with-desc (paper's sign)"]
    sub = df[(df["status"] == "ok") & df["method"].isin([full, without])]
    k_inf = int(np.isinf(sub["psnr"]).sum())
    notes += [f"{k_inf} identical pair(s) (PSNR = inf) excluded from PSNR means"] if k_inf else []
    return Table(disp, notes, _pooled_tidy(records), caption=POOLED_CAPTION)


def table_sensitivity(df: pd.DataFrame, keep: float = 0.7):
    method = catalog.proposed_method()
    r = ratios.from_keep(keep)
    sub = df[(df["method"] == method) & _at(df, r)]
    knobs = list(SENSITIVITY_KNOBS)

    def knob(v: str) -> str | None:  # sweep variants are named "<param>=<value>"
        return next((k for k in knobs if v.startswith(f"{k}=")), None)

    variants = [v for v in dict.fromkeys(sub["variant"]) if v == "default" or knob(v)]
    if len(variants) < 2:
        return Missing(f"needs {method}'s default variant and at least one sweep variant "
                       f"({' / '.join(f'{k}=…' for k in knobs)}) at keep {keep:g}; found "
                       f"{', '.join(variants) or 'none'}")
    variants = sorted(variants, key=lambda v: (v != "default", knobs.index(knob(v)) if knob(v) else -1, v))
    df, common = _common(df, [(method, v, r) for v in variants])
    idx, rows, records = [], [], []
    for v in variants:
        p = _pooled(df, method, r, v)
        knob_label = "baseline" if v == "default" else SENSITIVITY_KNOBS[knob(v)]
        idx.append((knob_label, v))
        rows.append([p["psnr"], p["ssim"], p["lpips"], p["n"], p["n_inf"]])
        records.append(({"knob": knob_label, "variant": v, "method": method, "ratio": r, "keep": keep}, p))
    num = pd.DataFrame(rows, pd.MultiIndex.from_tuples(idx, names=["knob", "variant"]),
                       ["PSNR (↑)", "SSIM (↑)", "LPIPS (↓)", "pairs", "inf"])
    disp = num.copy().astype(object)
    for j, d in enumerate([2, 4, 4, 0, 0]):
        disp.iloc[:, j] = [(_fmt(v, d) if d else str(int(v))) for v in num.iloc[:, j]]
    spread = num["PSNR (↑)"].replace(np.inf, np.nan)
    notes = [f"{method} at keep {keep} on the scenes every variant ran on ({', '.join(common)}); "
             f"PSNR spread across variants {spread.max() - spread.min():.2f} dB",
             "the paper gives values only for the baseline preset; flat, opacity-heavy and "
             "structure-heavy are this project's own coefficients"]
    return Table(disp, notes, _pooled_tidy(records), caption=POOLED_CAPTION.replace("the pairs columns", "pairs"))


def table_runtime(s: pd.DataFrame):
    """Scoring seconds per scene and method (the summary's ``score_s``: the mean over frames, with
    ``score_s_std`` over frames in the .csv)."""
    d = s[s["variant"] == "default"].drop_duplicates(["label", "method"])
    if d.empty:
        return Missing("no measured default variant")
    wide = d.pivot(index="label", columns="method", values="score_s")
    wide = wide[catalog.method_order(wide.columns)]
    tidy = d[["scene", "label", "method", "score_s", "score_s_std", "frames", "splats_in"]].copy()
    tidy.insert(3, "method_label", [catalog.method_label(m) for m in tidy["method"]])
    wide.insert(0, "splats", d.drop_duplicates("label").set_index("label")["splats_in"].reindex(wide.index))
    pair = catalog.descriptor_pair()
    notes = ["scoring seconds per scene (mean over frames), as measured by the run that computed them"]
    if pair is not None and pair[0] in wide and pair[1] in wide:
        without, full = pair
        wide["desc. overhead (s)"] = wide[full] - wide[without]
        wide["desc. overhead (%)"] = (100 * wide["desc. overhead (s)"] / wide[without]).where(wide[without] >= MIN_BASE_S)
        if wide["desc. overhead (%)"].isna().any():
            notes.append(f"desc. overhead (%): – where {catalog.method_label(without)} took under {MIN_BASE_S:g} s "
                         "(a percentage of so short a time says nothing); the seconds column still holds")
    wide.index.name = "scene"
    wide.columns = [catalog.method_label(c) + (" (s)" if c in d["method"].values else "") for c in wide.columns]
    disp = wide.copy().astype(object)
    for c in wide.columns:
        disp[c] = [str(int(v)) if c == "splats" and np.isfinite(v) else _fmt(v, 1 if "%" in c else 2) for v in wide[c]]
    frames = d["frames"].astype(int)
    n = f"{frames.min()}" if frames.min() == frames.max() else f"{frames.min()}–{frames.max()}"
    return Table(disp, notes, tidy.reset_index(drop=True),
                 caption=f"n = {n} frame(s) per scene, one scoring run each (the time of the run that computed it); "
                         "no interval")


BUILDERS = {"comparison": cells.table_comparison, "ablation": cells.table_ablation, "keep": table_keep,
            "sensitivity": table_sensitivity, "runtime": table_runtime, "per_scene": cells.table_per_scene,
            "versus": cells.table_versus, "bd": bd.table_bd, "ctc": bd.table_ctc}
#: builders that read the summary (one row per cell) rather than the per-view results
_USES_SUMMARY = {"runtime", "bd", "ctc"}
TITLES = {"comparison": "Comparison at low (10 %), mid (20 %) and high (30 %) pruning (paper Table 1)",
          "ablation": "Ablation: descriptors × Beta at 20 % pruning (paper Table 2)",
          "keep": "Keep fractions 0.7 / 0.5 / 0.3 with and without descriptors (paper Table 3)",
          "sensitivity": "Sensitivity: coefficient presets and voxel sizes at keep 0.7",
          "runtime": "Scoring runtime per scene", "per_scene": "Per-scene descriptor gains",
          "versus": "Every method against the reference, per view",
          "bd": "Bjøntegaard deltas against the anchor (BD-rate on .ply bytes; RGB-PSNR, YUV-PSNR, YUV-SSIM)",
          "ctc": "Per sequence and rate point (MPEG CTC layout)"}


def _call(fn, data, opts: dict):
    """``fn(data, **the opts its signature names)`` (options such as ``reference=``)."""
    params = inspect.signature(fn).parameters
    return fn(data, **{k: v for k, v in opts.items() if k in params and v is not None})


def build_tables(df: pd.DataFrame, names, **opts) -> dict[str, Table | Missing]:
    """Each named table built from the results (a :class:`Missing` where it cannot be)."""
    s = summarise(df)
    return {name: as_table(_call(BUILDERS[name], s if name in _USES_SUMMARY else df, opts)) for name in names}


#: the tables a config or ``harness tables --tables`` can name
TABLES = tuple(BUILDERS)


def title(name: str, protocol: str) -> str:
    """A table's title, with the held-out view protocol its rows come from (every protocol, the
    primary one too; none only for results that carry no protocol)."""
    base = TITLES.get(name, name)
    return base + (f" — held-out views: {protocol} ({PROTOCOL_NOTES.get(protocol, 'a named view protocol')})"
                   if protocol else "")


def with_caption(t: Table | Missing) -> Table | Missing:
    """``t`` with a caption: its own, else one read from its tidy rows — ``n`` per cell where they
    carry it, and the interval method where they carry intervals (every table's caption says both)."""
    if isinstance(t, Missing) or t.caption:
        return t
    from harness.report import stats

    parts = []
    if "n" in t.tidy and t.tidy["n"].notna().any():
        lo, hi = int(t.tidy["n"].min()), int(t.tidy["n"].max())
        parts.append(f"n = {lo if lo == hi else f'{lo}–{hi}'} per cell")
    parts.append(f"intervals: {stats.INTERVAL_DESCRIPTION}" if {"ci_low", "ci_high"} <= set(t.tidy)
                 else "no interval")
    return dataclasses.replace(t, caption="; ".join(parts))


def write_tables(df: pd.DataFrame, out_dir: str | Path, names, **opts) -> Written:
    """Write ``tables/<name>.md|csv|tex`` for each table that can be made, plus ``tables/summary.csv``,
    per held-out view protocol (:func:`harness.report.summary.protocol_subsets`): the primary
    (training rig) one as ``<name>.*``, the others as ``<name>-<protocol>.*``; every title, caption
    and tidy row names its protocol. Tables these results cannot make are listed in ``missing``;
    their files from an earlier build are removed, since they describe other results than the
    ``results.parquet`` beside them (``missing`` says so)."""
    from harness.report.formats import to_latex, to_markdown

    out_dir = Path(out_dir) / "tables"
    out_dir.mkdir(parents=True, exist_ok=True)
    subsets = protocol_subsets(df)
    summaries = [summarise(sub).assign(protocol=proto) for proto, _, sub in subsets]
    out = Written([out_dir / "summary.csv"])
    atomic_write_text(out.paths[0], pd.concat(summaries, ignore_index=True).to_csv(index=False))
    for proto, suffix, sub in subsets:
        for name, t in build_tables(sub, names, **opts).items():
            t = with_caption(t)
            key = name + suffix
            out.built[key] = Built(key, name, proto, title(name, proto), t)
            if isinstance(t, Missing):
                stale = [f for ext in ("md", "csv", "tex") if (f := out_dir / f"{key}.{ext}").exists()]
                for f in stale:
                    f.unlink()
                out.missing.append(f"table {key} not written: {t.reason}"
                                   + (f" (removed its earlier {', '.join(f.name for f in stale)})" if stale else ""))
                continue
            out.warnings += t.warnings
            tidy = t.tidy.assign(protocol=proto)
            for ext, text in (("md", to_markdown(t, out.built[key].title)), ("csv", tidy.to_csv(index=False)),
                              ("tex", to_latex(t.disp, out.built[key].title, [t.caption, *t.notes],
                                               label=f"table:{key}"))):
                path = out_dir / f"{key}.{ext}"
                atomic_write_text(path, text)
                out.paths.append(path)
    return out
