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

import inspect
from pathlib import Path

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.io.files import atomic_write_text
from harness.report import bd, catalog, cells, photos
from harness.report.summary import PRIMARY_PROTOCOL, PROTOCOL_NOTES, protocol_subsets, summarise
from harness.report.tabledata import Missing, Table, Written, as_table

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
    ok = df[(df["status"] == "ok") & (df["method"] == method) & (df["variant"] == variant)
            & _at(df, ratio)]
    fin = ok["psnr"][np.isfinite(ok["psnr"])]
    return {"psnr": fin.mean() if len(fin) else (np.inf if len(ok) else np.nan), "ssim": ok["ssim"].mean(),
            "lpips": ok["lpips"].mean(), "n": len(ok), "n_inf": int(np.isinf(ok["psnr"]).sum())}


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
    rows, idx = [], []
    for k in KEEPS:
        r = ratios.from_keep(k)
        sub, _ = _common(df, [(without, "default", r), (full, "default", r)])
        a, b = _pooled(sub, without, r), _pooled(sub, full, r)
        if a["n"] == 0 and b["n"] == 0:
            continue
        idx.append(ratios.percent(r))
        rows.append([a["psnr"], a["ssim"], a["lpips"], b["psnr"], b["ssim"], b["lpips"], a["psnr"] - b["psnr"],
                     a["n"], b["n"]])
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
    return num, disp, notes + ([f"{k_inf} identical pair(s) (PSNR = inf) excluded from PSNR means"] if k_inf else [])


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
    idx, rows = [], []
    for v in variants:
        p = _pooled(df, method, r, v)
        knob_label = "baseline" if v == "default" else SENSITIVITY_KNOBS[knob(v)]
        idx.append((knob_label, v))
        rows.append([p["psnr"], p["ssim"], p["lpips"], p["n"], p["n_inf"]])
    num = pd.DataFrame(rows, pd.MultiIndex.from_tuples(idx, names=["knob", "variant"]),
                       ["PSNR (↑)", "SSIM (↑)", "LPIPS (↓)", "pairs", "inf"])
    disp = num.copy().astype(object)
    for j, d in enumerate([2, 4, 4, 0, 0]):
        disp.iloc[:, j] = [(_fmt(v, d) if d else str(int(v))) for v in num.iloc[:, j]]
    spread = num["PSNR (↑)"].replace(np.inf, np.nan)
    return num, disp, [f"{method} at keep {keep} on the scenes every variant ran on ({', '.join(common)}); "
                       f"PSNR spread across variants {spread.max() - spread.min():.2f} dB",
                       "the paper gives values only for the baseline preset; flat, opacity-heavy and "
                       "structure-heavy are this project's own coefficients"]


def table_runtime(s: pd.DataFrame):
    d = s[s["variant"] == "default"].drop_duplicates(["label", "method"])
    if d.empty:
        return Missing("no measured default variant")
    wide = d.pivot(index="label", columns="method", values="score_s")
    wide = wide[catalog.method_order(wide.columns)]
    tidy = d[["scene", "label", "method", "score_s", "splats_in"]].copy()
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
    return Table(disp, notes, tidy.reset_index(drop=True))


BUILDERS = {"comparison": cells.table_comparison, "ablation": cells.table_ablation, "keep": table_keep,
            "sensitivity": table_sensitivity, "runtime": table_runtime, "per_scene": cells.table_per_scene,
            "versus": cells.table_versus, "bd": bd.table_bd, "ctc": bd.table_ctc, "photos": photos.table_photos}
#: builders that read the summary (one row per cell) rather than the per-view results
_USES_SUMMARY = {"runtime", "bd", "ctc"}
TITLES = {"comparison": "Comparison at low (10 %), mid (20 %) and high (30 %) pruning (paper Table 1)",
          "ablation": "Ablation: descriptors × Beta at 20 % pruning (paper Table 2)",
          "keep": "Keep fractions 0.7 / 0.5 / 0.3 with and without descriptors (paper Table 3)",
          "sensitivity": "Sensitivity: coefficient presets and voxel sizes at keep 0.7",
          "runtime": "Scoring runtime per scene", "per_scene": "Per-scene descriptor gains",
          "versus": "Every method against the reference, per view",
          "bd": "Bjøntegaard deltas against the anchor (BD-rate on .ply bytes; RGB-PSNR, YUV-PSNR, YUV-SSIM)",
          "ctc": "Per sequence and rate point (MPEG CTC layout)",
          "photos": "Against the captured photos: pruned and unpruned renders, per held-out view"}


def _call(fn, data, opts: dict):
    """``fn(data, **the opts its signature names)`` (options such as ``reference=``)."""
    params = inspect.signature(fn).parameters
    return fn(data, **{k: v for k, v in opts.items() if k in params and v is not None})


def build_tables(df: pd.DataFrame, names, **opts) -> dict[str, Table | Missing]:
    """Each named table built from the results (a :class:`Missing` where it cannot be)."""
    s = summarise(df)
    return {name: as_table(_call(BUILDERS[name], s if name in _USES_SUMMARY else df, opts)) for name in names}


def write_tables(df: pd.DataFrame, out_dir: str | Path, names, **opts) -> Written:
    """Write ``tables/<name>.md|csv|tex`` for each table that can be made, plus ``tables/summary.csv``;
    the others are listed in ``missing`` (and their files from an earlier build removed). A run with
    several held-out view protocols gets each table per protocol: the primary (training rig) one as
    ``<name>.*``, the others as ``<name>-<protocol>.*`` (:func:`harness.report.summary.protocol_subsets`)."""
    from harness.report.formats import to_latex, to_markdown

    out_dir = Path(out_dir) / "tables"
    out_dir.mkdir(parents=True, exist_ok=True)
    subsets = protocol_subsets(df)
    with_photos = {proto for proto, _, sub in subsets if not photos._views(sub).empty}
    summaries = [summarise(sub).assign(protocol=proto) if len(subsets) > 1 else summarise(sub)
                 for proto, _, sub in subsets]
    out = Written([out_dir / "summary.csv"])
    atomic_write_text(out.paths[0], pd.concat(summaries, ignore_index=True).to_csv(index=False))
    for proto, suffix, sub in subsets:
        # the photos table belongs to the protocols whose views have photos (when any has)
        here = [n for n in names if n != "photos" or not with_photos or proto in with_photos]
        for name, t in build_tables(sub, here, **opts).items():
            key = name + suffix
            out.built[key] = t
            if isinstance(t, Missing):
                out.missing.append(f"table {key} not written: {t.reason}")
                for ext in ("md", "csv", "tex"):
                    (out_dir / f"{key}.{ext}").unlink(missing_ok=True)
                continue
            out.warnings += t.warnings
            title = TITLES.get(name, name)
            if len(subsets) > 1 or proto not in ("", PRIMARY_PROTOCOL):  # every table names a non-rig protocol
                title += f" — held-out views: {proto} ({PROTOCOL_NOTES.get(proto, 'a named view protocol')})"
                if not suffix:  # its file name does not say it (the report page shows the notes)
                    t.notes = [*t.notes, f"held-out views: {proto} ({PROTOCOL_NOTES.get(proto, 'a named view protocol')})"]
            tidy = t.tidy.assign(protocol=proto) if len(subsets) > 1 else t.tidy
            for ext, text in (("md", to_markdown(t, title)), ("csv", tidy.to_csv(index=False)),
                              ("tex", to_latex(t.disp, title, t.notes, label=f"table:{key}"))):
                path = out_dir / f"{key}.{ext}"
                atomic_write_text(path, text)
                out.paths.append(path)
    return out
