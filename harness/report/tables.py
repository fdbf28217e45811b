"""The paper's tables from tidy results (pandas), as markdown, csv and LaTeX.

Means are over all measured image pairs of a cell (every view of every frame of a sequence). PSNR
= +inf (pruned render identical to the reference) is excluded from PSNR means and counted in
``n_inf`` (``summary.csv``; a note under each table); a cell whose pairs are all identical shows
``inf``. Only ``status == ok`` rows enter.

Which methods go where is asked of the pruner registry (:mod:`harness.report.catalog`): labels,
comparison groups, and each method's cell of the paper's ablation grid.

* ``comparison`` (Table 1): per scene × metric, each method's default variant at Low/Mid/High =
  10/20/30 % pruning, grouped as the registry groups them (camera-aware methods, simple baselines,
  the paper's method, other registered methods).
* ``ablation`` (Table 2): at 20 %, No/With Descriptors × No Beta/Beta (betadesc-nodesc-nobeta,
  betadesc-nodesc, betadesc-nobeta, betadesc). Bold: best per row.
* ``keep`` (Table 3): keep 0.7/0.5/0.3 (prune 30/50/70 %), pooled over scenes, betadesc-nodesc
  vs betadesc, and ΔPSNR = PSNR(no descriptors) − PSNR(with descriptors) — the paper's sign
  (negative when descriptors help).
* ``sensitivity``: betadesc variants at keep 0.7 — coefficient presets and voxel sizes (variants
  named ``preset=…`` / ``voxel=…``; the default variant is the baseline row).
* ``runtime``: scoring seconds per scene of every method's default variant, with the descriptor
  overhead betadesc − betadesc-nodesc (absolute and %).
* ``per_scene``: per-scene descriptor gain PSNR(betadesc) − PSNR(betadesc-nodesc) at each keep
  fraction (positive = descriptors help; the paper's "+4.04 dB" sense).
* ``bd`` and ``ctc``: rate points, BD-rate / BD-PSNR against the config's anchor, and the CTC's
  per-sequence CSV layout (:mod:`harness.report.bd`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.io.files import atomic_write_text
from harness.report import bd, catalog
from harness.report.summary import summarise

LEVELS = (("Low", 0.1), ("Mid", 0.2), ("High", 0.3))
KEEPS = (0.7, 0.5, 0.3)
#: the paper's sensitivity knobs (Table 4): swept parameter -> row group
SENSITIVITY_KNOBS = {"preset": "coefficients", "voxel": "voxel size"}


def _at(df: pd.DataFrame, ratio: float) -> pd.Series:
    """Rows of ``df`` at pruning ratio ``ratio``."""
    return (df["ratio"] - ratio).abs() <= ratios.TOLERANCE


def _metrics(s: pd.DataFrame | None = None) -> list[tuple[str, str, int]]:
    """(name, heading, digits) of the metrics to show: the 3DGS set, or every registered metric
    ``s`` has values for (MPEG columns carry the tool's names: RGB-PSNR, YUV-PSNR, YUV-SSIM, OM-…)."""
    if s is None:
        return catalog.metric_columns(("psnr", "ssim", "lpips"))
    return [c for c in catalog.metric_columns(s.columns) if s[c[0]].notna().any()]




def _cell(s: pd.DataFrame, scene, method, ratio, variant="default"):
    m = s[(s["label"] == scene) & (s["method"] == method) & (s["variant"] == variant)
          & _at(s, ratio)]
    return None if m.empty else m.iloc[0]


def _fmt(v, digits: int) -> str:
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return "–"
    if np.isinf(v):
        return "inf"
    return f"{v:.{digits}f}"


def _inf_note(s: pd.DataFrame) -> list[str]:
    k = int(s["n_inf"].sum()) if len(s) else 0
    return [f"PSNR means exclude {k} identical-image pair(s) (PSNR = inf); counts per cell in summary.csv."] if k else []


# --------------------------------------------------------------------------- tables
def table_comparison(s: pd.DataFrame):
    cols = [(grp, catalog.method_label(m), lvl, m, r) for grp, m in catalog.comparison_methods(s["method"])
            for lvl, r in LEVELS]
    if not cols:
        return None
    idx, num, disp = [], [], []
    for scene in dict.fromkeys(s["label"]):
        for key, name, digits in _metrics(s):
            cells = [_cell(s, scene, m, r) for *_, m, r in cols]
            vals = [np.nan if c is None else c[key] for c in cells]
            idx.append((scene, name))
            num.append(vals)
            disp.append([_fmt(v, digits) for v in vals])
    mi = pd.MultiIndex.from_tuples([c[:3] for c in cols], names=["group", "method", "level"])
    ri = pd.MultiIndex.from_tuples(idx, names=["Dataset", "Metric"])
    return pd.DataFrame(num, ri, mi), pd.DataFrame(disp, ri, mi), _inf_note(s)


def table_ablation(s: pd.DataFrame, ratio: float = 0.2):
    present = [a for a in catalog.ablation_cells()
               if not s[(s["method"] == a[2]) & _at(s, ratio)].empty]
    if not present:
        return None
    idx, num, disp = [], [], []
    for scene in dict.fromkeys(s["label"]):
        for key, name, digits in _metrics(s):
            vals = [np.nan if (c := _cell(s, scene, m, ratio)) is None else c[key] for *_, m in present]
            finite = [v for v in vals if np.isfinite(v)]
            best = (max(finite) if catalog.higher_is_better(key) else min(finite)) if finite else None
            idx.append((scene, name))
            num.append(vals)
            disp.append([f"**{_fmt(v, digits)}**" if best is not None and v == best else _fmt(v, digits)
                         for v in vals])
    mi = pd.MultiIndex.from_tuples([a[:2] for a in present], names=["descriptors", "beta"])
    ri = pd.MultiIndex.from_tuples(idx, names=["Dataset", "Metric"])
    return pd.DataFrame(num, ri, mi), pd.DataFrame(disp, ri, mi), _inf_note(s[_at(s, ratio)])


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
        return None
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
        return None
    mi = pd.MultiIndex.from_tuples(
        [("No Descriptors", m) for _, m, _ in _metrics()] + [("With Descriptors", m) for _, m, _ in _metrics()]
        + [("ΔPSNR", "(dB)"), ("pairs", "no desc."), ("pairs", "with desc.")])
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
        return None
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
                       f"PSNR spread across variants {spread.max() - spread.min():.2f} dB"]


def table_runtime(s: pd.DataFrame):
    d = s[s["variant"] == "default"].drop_duplicates(["label", "method"])
    if d.empty:
        return None
    wide = d.pivot(index="label", columns="method", values="score_s")
    wide = wide[catalog.method_order(wide.columns)]
    wide.insert(0, "splats", d.drop_duplicates("label").set_index("label")["splats_in"].reindex(wide.index))
    pair = catalog.descriptor_pair()
    if pair is not None and pair[0] in wide and pair[1] in wide:
        without, full = pair
        wide["desc. overhead (s)"] = wide[full] - wide[without]
        wide["desc. overhead (%)"] = 100 * wide["desc. overhead (s)"] / wide[without]
    wide.index.name = "scene"
    wide.columns = [catalog.method_label(c) + (" (s)" if c in d["method"].values else "") for c in wide.columns]
    disp = wide.copy().astype(object)
    for c in wide.columns:
        disp[c] = [str(int(v)) if c == "splats" and np.isfinite(v) else _fmt(v, 1 if "%" in c else 2) for v in wide[c]]
    return wide, disp, ["scoring seconds per scene (mean over frames), as measured by the run that computed them"]


def table_per_scene(s: pd.DataFrame):
    pair = catalog.descriptor_pair()
    if pair is None:
        return None
    without, full = pair
    rows, idx = [], []
    for scene in dict.fromkeys(s["label"]):
        gains = []
        for k in KEEPS:
            a, b = _cell(s, scene, without, ratios.from_keep(k)), _cell(s, scene, full, ratios.from_keep(k))
            gains.append(np.nan if a is None or b is None else b["psnr"] - a["psnr"])
        if not all(np.isnan(g) for g in gains):
            idx.append(scene)
            rows.append(gains)
    if not rows:
        return None
    num = pd.DataFrame(rows, pd.Index(idx, name="scene"), [f"prune {ratios.percent(ratios.from_keep(k))}" for k in KEEPS])
    disp = num.map(lambda v: "–" if np.isnan(v) else f"{v:+.2f}")
    return num, disp, [f"descriptor gain in dB: PSNR({full}) − PSNR({without}); positive = descriptors help"]


BUILDERS = {"comparison": table_comparison, "ablation": table_ablation, "keep": table_keep,
            "sensitivity": table_sensitivity, "runtime": table_runtime, "per_scene": table_per_scene,
            "bd": bd.table_bd, "ctc": bd.table_ctc}
_USES_RAW = {"keep", "sensitivity"}
TITLES = {"comparison": "Comparison at low (10 %), mid (20 %) and high (30 %) pruning (paper Table 1)",
          "ablation": "Ablation: descriptors × Beta at 20 % pruning (paper Table 2)",
          "keep": "Keep fractions 0.7 / 0.5 / 0.3 with and without descriptors (paper Table 3)",
          "sensitivity": "Sensitivity: coefficient presets and voxel sizes at keep 0.7",
          "runtime": "Scoring runtime per scene", "per_scene": "Per-scene descriptor gains",
          "bd": "Bjøntegaard deltas against the anchor (BD-rate on .ply bytes; RGB-PSNR, YUV-PSNR, YUV-SSIM)",
          "ctc": "Per sequence and rate point (MPEG CTC layout)"}


def build_tables(df: pd.DataFrame, names, anchor: str | None = None) -> dict:
    s = summarise(df)
    out = {}
    for name in names:
        t = bd.table_bd(s, anchor) if name == "bd" else BUILDERS[name](df if name in _USES_RAW else s)
        if t is not None:
            out[name] = t
    return out


def write_tables(df: pd.DataFrame, out_dir: str | Path, names, anchor: str | None = None) -> list[Path]:
    """Write ``tables/<name>.md|csv|tex`` for each table with data, plus ``tables/summary.csv``."""
    from harness.report.formats import to_latex, to_markdown

    out_dir = Path(out_dir) / "tables"
    out_dir.mkdir(parents=True, exist_ok=True)
    s = summarise(df)
    written = [out_dir / "summary.csv"]
    atomic_write_text(written[0], s.to_csv(index=False))
    for name, (num, disp, notes) in build_tables(df, names, anchor).items():
        title = TITLES[name]
        for ext, text in (("md", to_markdown(disp, title, notes)), ("csv", num.to_csv()),
                          ("tex", to_latex(disp, title, notes, label=f"table:{name}"))):
            p = out_dir / f"{name}.{ext}"
            atomic_write_text(p, text)
            written.append(p)
    return written
