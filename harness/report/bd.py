"""Rate points and Bjøntegaard deltas, as the MPEG CTC reports a codec: per sequence and rate point,
then BD-rate / BD-PSNR of each method against an anchor.

**Rate points.** A pruning ratio is an operating point; the rate is the size of the pruned ``.ply``
the harness writes (``bytes``, exact, :mod:`harness.io.plysize`), with ``splats`` beside it. Every
ratio of a run is one rate point, labelled by falling ratio: ``RP1`` is the most pruned (lowest
rate). The paper's High / Mid / Low (30 / 20 / 10 % pruned) are therefore consecutive rate points,
RP1–RP3 when those are the run's only ratios.

**Quality per rate point** is the tool's average (``Metric::getAverage``): the mean over every view
(and frame) of the per-view value, PSNRs in dB; the rate is the mean size per frame.

**BD metrics** (Bjøntegaard, VCEG-M33) via the maintained ``bjontegaard`` package
(FAU, BSD, pinned in pyproject): with log10(rate) as the rate axis,

* BD-rate = (10^(mean over the common quality range of log-rate_test − log-rate_anchor) − 1)·100 %:
  the size change at equal quality (negative: the method needs fewer bytes than the anchor);
* BD-PSNR (BD-SSIM for YUV-SSIM) = the mean over the common log-rate range of quality_test −
  quality_anchor. For YUV-SSIM the BD-rate integrates over SSIM in dB, −10·log10(1 − SSIM): SSIMs
  crowd just below 1 and a cubic fit in raw SSIM oscillates (on luigi it turned +47 % into −97 %).

Interpolation: ``cubic`` (the classic third-order polynomial fit) when both curves have ≥ 4 rate
points, ``pchip`` (piecewise cubic Hermite; what JVET's CTC sheets use) with 2 or 3 — each cell says
which. A curve that is not strictly monotone (quality falls as rate grows), or curves without
overlap, give no value ("–") and a note. The anchor comes from the config (``anchor:``, default
``lightgs``); BD values are per scene and averaged over the scenes that have them.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.report.tabledata import Table, tidy_with_std

DEFAULT_ANCHOR = "lightgs"
#: (column, CTC name) of the qualities BD is reported for
BD_METRICS = (("rgb_psnr", "RGB-PSNR"), ("yuv_psnr", "YUV-PSNR"), ("yuv_ssim", "YUV-SSIM"))
#: the CTC per-sequence CSV: (summary column, CSV heading)
CTC_COLUMNS = (("splats_out", "splats"), ("bytes", "bytes"), ("rgb_psnr", "RGB-PSNR"), ("yuv_psnr", "YUV-PSNR"),
               ("yuv_ssim", "YUV-SSIM"), ("rgb_psnr_om", "OM-RGB-PSNR"), ("yuv_psnr_om", "OM-YUV-PSNR"),
               ("yuv_ssim_om", "OM-YUV-SSIM"), ("occupancy", "Occupancy"), ("lpips", "LPIPS"), ("psnr", "PSNR"),
               ("ssim", "SSIM"))
LEVELS = {0.3: "High", 0.2: "Mid", 0.1: "Low"}


def interpolation(n_anchor: int, n_test: int) -> str:
    """``cubic`` with ≥ 4 points on both curves, else ``pchip`` (see the module docstring)."""
    return "cubic" if min(n_anchor, n_test) >= 4 else "pchip"


def _monotone(rate, quality) -> bool:
    order = np.argsort(rate)
    q = np.asarray(quality, float)[order]
    r = np.asarray(rate, float)[order]
    return bool(np.all(np.diff(r) > 0) and np.all(np.diff(q) > 0))


def ssim_db(q) -> np.ndarray:
    """SSIM on a dB scale, −10·log10(1 − SSIM) (1 − SSIM floored at 1e-12)."""
    return -10.0 * np.log10(np.maximum(1.0 - np.asarray(q, float), 1e-12))


def bd_pair(rate_anchor, q_anchor, rate_test, q_test, *, ssim: bool = False) -> tuple[float, float, str]:
    """(BD-rate %, BD-quality, interpolation) of a test curve against an anchor curve; NaN where
    undefined (fewer than 2 points, a non-monotone curve, no overlap). ``ssim=True``: the BD-rate
    integrates over SSIM in dB (:func:`ssim_db`; a cubic fit in raw SSIM, whose values crowd below
    1, oscillates), the BD-SSIM stays in SSIM units."""
    import bjontegaard

    ra, qa, rt, qt = (np.asarray(x, float) for x in (rate_anchor, q_anchor, rate_test, q_test))
    how = interpolation(len(ra), len(rt))
    if min(len(ra), len(rt)) < 2 or not (_monotone(ra, qa) and _monotone(rt, qt)):
        return math.nan, math.nan, how
    oa, ot = np.argsort(ra), np.argsort(rt)
    out = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for fn, qa_, qt_ in ((bjontegaard.bd_rate, ssim_db(qa) if ssim else qa, ssim_db(qt) if ssim else qt),
                             (bjontegaard.bd_psnr, qa, qt)):
            try:
                v = float(fn(ra[oa], qa_[oa], rt[ot], qt_[ot], how, require_matching_points=False, min_overlap=0))
            except (ValueError, np.linalg.LinAlgError):
                v = math.nan
            out.append(v)
    return out[0], out[1], how


def rate_points(s: pd.DataFrame) -> pd.DataFrame:
    """Summary rows (``harness.report.summary.summarise``) of the default variants with a rate, each
    labelled with its rate point ``RPk`` (k by falling ratio over the whole run) and paper level."""
    if s.empty or "bytes" not in s or s["bytes"].isna().all():
        return s.iloc[0:0].assign(rp=pd.Series(dtype=str), level=pd.Series(dtype=str))
    d = s[(s["variant"] == "default") & s["bytes"].notna()].copy()
    grid = sorted({ratios.key(r) for r in d["ratio"]}, reverse=True)
    d["rp"] = [f"RP{grid.index(ratios.key(r)) + 1}" for r in d["ratio"]]
    d["level"] = [next((v for k, v in LEVELS.items() if abs(k - r) <= ratios.TOLERANCE), "") for r in d["ratio"]]
    return d.sort_values(["label", "method", "ratio"], ascending=[True, True, False], kind="stable")


def bd_rows(s: pd.DataFrame, anchor: str = DEFAULT_ANCHOR) -> pd.DataFrame:
    """Long table: scene, method, metric, BD-rate %, BD-quality, points (test/anchor), interpolation."""
    d = rate_points(s)
    rows = []
    for scene, sd in d.groupby("label", sort=False):
        a = sd[sd["method"] == anchor]
        if a.empty:
            continue
        for method, md in sd.groupby("method", sort=False):
            if method == anchor:
                continue
            for col, name in BD_METRICS:
                if col not in md or md[col].isna().all() or a[col].isna().all():
                    continue
                rate, dq, how = bd_pair(a["bytes"], a[col], md["bytes"], md[col], ssim="ssim" in col)
                rows.append({"scene": scene, "method": method, "metric": name, "bd_rate": rate, "bd_quality": dq,
                             "points": f"{len(md)}/{len(a)}", "interp": how})
    return pd.DataFrame(rows, columns=["scene", "method", "metric", "bd_rate", "bd_quality", "points", "interp"])


def _scene_rows(long: pd.DataFrame, metrics: list[str], methods: list[str]) -> tuple[list, list]:
    """(index, values) of the per-scene rows: BD-rate and BD-quality per metric, points, interp."""
    from harness.report import catalog

    idx, num = [], []
    for scene in dict.fromkeys(long["scene"]):
        for method in methods:
            cell = long[(long["scene"] == scene) & (long["method"] == method)]
            if cell.empty:
                continue
            vals = []
            for m in metrics:
                r = cell[cell["metric"] == m]
                vals += [r["bd_rate"].iloc[0], r["bd_quality"].iloc[0]] if len(r) else [np.nan, np.nan]
            idx.append((scene, catalog.method_label(method)))
            num.append(vals + [cell["points"].iloc[0], cell["interp"].iloc[0]])
    return idx, num


def _average_rows(long: pd.DataFrame, metrics: list[str], methods: list[str]) -> tuple[list, list, list]:
    """(index, means, stds) of the average rows: per method, the mean over the scenes that have a
    value (the std over them beside it in the .csv)."""
    from harness.report import catalog

    idx, num, std = [], [], []
    for method in methods:
        vals, sds = [], []
        for m in metrics:
            r = long[(long["method"] == method) & (long["metric"] == m)]
            vals += [r["bd_rate"].mean(), r["bd_quality"].mean()]
            sds += [r["bd_rate"].std(ddof=1), r["bd_quality"].std(ddof=1)]
        n = int(long[(long["method"] == method)]["scene"].nunique())
        idx.append(("average", catalog.method_label(method)))
        num.append(vals + [f"{n} scenes", ""])
        std.append(sds + [np.nan, np.nan])
    return idx, num, std


def table_bd(s: pd.DataFrame, anchor: str | None = None):
    """The bd table: rows (scene | average, method), columns (metric, BD-rate % | BD-PSNR/SSIM)."""
    from harness.report import catalog

    anchor = anchor or DEFAULT_ANCHOR
    long = bd_rows(s, anchor)
    if long.empty:
        return None
    metrics = [name for _, name in BD_METRICS if name in set(long["metric"])]
    methods = catalog.method_order(long["method"])
    cols = pd.MultiIndex.from_tuples([(m, k) for m in metrics for k in ("BD-rate (%)", "BD-" + m.split("-")[1])]
                                     + [("", "points"), ("", "interp")])
    idx, num = _scene_rows(long, metrics, methods)
    avg_idx, avg_num, avg_std = _average_rows(long, metrics, methods)
    std = [[np.nan] * len(cols) for _ in num] + avg_std
    numdf = pd.DataFrame(num + avg_num, pd.MultiIndex.from_tuples(idx + avg_idx, names=["Sequence", "Method"]), cols)
    disp = numdf.copy().astype(object)
    for j, (m, k) in enumerate(cols[:-2]):
        d = 2 if "rate" in k or "PSNR" in k else 4
        disp.iloc[:, j] = ["–" if not np.isfinite(v) else f"{v:+.{d}f}" for v in numdf.iloc[:, j].astype(float)]
    notes = [f"anchor: {catalog.method_label(anchor)} ({anchor}); rate = bytes of the pruned .ply (mean per frame), "
             "quality = mean over views and frames; BD-rate < 0: fewer bytes than the anchor at equal quality",
             "interpolation: cubic (≥ 4 rate points on both curves), else pchip; points = test/anchor rate points",
             "– : curve not strictly monotone, fewer than 2 points, or no overlap with the anchor"]
    n_scenes = long["scene"].nunique()
    return Table(disp, notes, tidy_with_std(numdf, pd.DataFrame(std, numdf.index, cols)),
                 caption=f"n = rate points per curve (points column); average over {n_scenes} scene(s); no "
                         "interval (the .csv has the std over scenes beside each average)")


def _ctc_digits(column: str) -> int:
    """Digits of a CTC column: counts whole, SSIM-like and LPIPS 4, the others 2."""
    if column in ("splats", "bytes"):
        return 0
    return 4 if "SSIM" in column or column == "LPIPS" else 2


def _ctc_text(v, digits: int) -> str:
    if pd.isna(v):
        return "–"
    return f"{int(v)}" if digits == 0 else f"{float(v):.{digits}f}"


def table_ctc(s: pd.DataFrame):
    """The CTC per-sequence layout: one row per (sequence, method, rate point), default variants."""
    d = rate_points(s)
    if d.empty:
        return None
    d = d.assign(seconds=d["score_s"].astype(float) + d.get("prune_s", 0.0))
    cols = [(c, h) for c, h in CTC_COLUMNS if c in d and d[c].notna().any()]
    out = pd.DataFrame({"Sequence": d["label"], "Method": d["method"], "RP": d["rp"], "ratio": d["ratio"],
                        "level": d["level"], **{h: d[c] for c, h in cols}, "seconds": d["seconds"]})
    out = out.set_index(["Sequence", "Method", "RP"])
    disp = out.copy().astype(object)
    for c in disp.columns.drop("level"):
        disp[c] = [_ctc_text(v, _ctc_digits(c)) for v in out[c]]
    std = pd.DataFrame({h: d[f"{c}_std"].to_numpy() if f"{c}_std" in d else np.nan for c, h in cols},
                       index=out.index)
    n = d["n"].astype(int)
    return Table(disp, ["splats and bytes: mean per frame of the pruned .ply; metrics: mean over views and frames; "
                        "seconds: scoring + selection time of the method"], tidy_with_std(out, std),
                 caption=f"n = {n.min() if n.min() == n.max() else f'{n.min()}–{n.max()}'} view(s) per row (all "
                         "frames); no interval (the .csv has each mean's std)")
