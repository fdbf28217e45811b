"""The ``photos`` table: renders against the captured photos (the ``real`` protocol's views).

The paper states two kinds of numbers: "against captured ground-truth images" and "between the
pruned render and the non-pruned render". The other tables carry both (``PSNR`` and ``PSNR vs
photo`` sections); this one answers the question the photos add: how much fidelity to the real
scene does pruning cost? Per scene, method (comparison order, default variants) and ratio, for each
photo metric: the mean over the held-out views of the pruned render against the photo, and
Δ = pruned − unpruned against the same photo, paired per view, with its 95 % bootstrap CI
(:mod:`harness.report.stats`). Each scene's first line is the unpruned render itself.

Which metrics: ``PSNR vs photo``, its occupancy-masked variant (the pixels the unpruned render
covers — on a cropped scene the rest of the photo is background the splats never held), SSIM and
LPIPS vs photo, and the MPEG set's twins when measured (:data:`METRICS`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.report import catalog, stats
from harness.report.cells import fmt
from harness.report.tabledata import Missing, Table

#: the photo metrics shown, in this order, where the results have them
METRICS = ("gt_psnr", "gt_psnr_om", "gt_ssim", "gt_lpips", "gt_rgb_psnr", "gt_yuv_psnr", "gt_yuv_ssim",
           "gt_rgb_psnr_om", "gt_yuv_psnr_om", "gt_yuv_ssim_om")
UNPRUNED = "unpruned"
TIDY = ["table", "scene", "label", "method", "method_label", "variant", "ratio", "metric", "mean", "unpruned",
        "delta", "ci_low", "ci_high", "n_pairs", "verdict", "occupancy"]


def _views(df: pd.DataFrame) -> pd.DataFrame:
    """Measured rows of views with a photo."""
    ok = df[(df["status"] == "ok")] if "status" in df else df
    return ok[ok["gt_psnr"].notna()] if "gt_psnr" in ok else ok.iloc[0:0]


def has_photos(df: pd.DataFrame) -> bool:
    """Do any measured rows of ``df`` come from views with a photo?"""
    return not _views(df).empty


def table_photos(df: pd.DataFrame) -> Table | Missing:
    ok = _views(df)
    if ok.empty:
        return Missing("no measured view has a captured photo (scenes with a capture, under the `real` protocol)")
    mets = [m for m in METRICS if m in ok and ok[m].notna().any() and f"unpruned_{m}" in ok]
    methods = [m for _, m in catalog.comparison_methods(ok["method"])] or catalog.method_order(ok["method"])
    ok = ok[ok["variant"] == "default"]
    records = []
    for scene, g in ok.groupby("scene", sort=False):
        label, occ = g["label"].iloc[0], float(g["unpruned_gt_occupancy"].mean())
        views = g.drop_duplicates(["frame", "view"])
        for m in mets:
            base = views[f"unpruned_{m}"].to_numpy(np.float64)
            records.append({"table": "photos", "scene": scene, "label": label, "method": UNPRUNED,
                            "method_label": "unpruned", "variant": "", "ratio": 0.0, "metric": m,
                            "mean": float(np.nanmean(base)), "unpruned": float(np.nanmean(base)),
                            "n_pairs": int(np.isfinite(base).sum()), "occupancy": occ})
        for method in methods:
            for r, c in g[g["method"] == method].groupby("ratio", sort=True):
                for m in mets:
                    d = (c[m] - c[f"unpruned_{m}"]).to_numpy(np.float64)
                    d = d[np.isfinite(d)]
                    lo, hi = stats.bootstrap_ci(d)
                    records.append({"table": "photos", "scene": scene, "label": label, "method": method,
                                    "method_label": catalog.method_label(method), "variant": "default",
                                    "ratio": float(r), "metric": m, "mean": float(c[m].mean()),
                                    "unpruned": float(c[f"unpruned_{m}"].mean()),
                                    "delta": float(d.mean()) if d.size else np.nan, "ci_low": lo, "ci_high": hi,
                                    "n_pairs": int(d.size), "occupancy": occ,
                                    "verdict": stats.verdict(lo, hi, catalog.higher_is_better(m))})
    tidy = pd.DataFrame(records, columns=TIDY)
    return Table(_wide(tidy, mets), _notes(tidy), tidy, _sections(tidy, mets))


def _text(r, digits: int) -> str:
    if r["method"] == UNPRUNED:
        return fmt(r["mean"], digits)
    ci = "" if pd.isna(r["ci_low"]) else f" [{fmt(r['ci_low'], digits, True)}, {fmt(r['ci_high'], digits, True)}]"
    return f"{fmt(r['mean'], digits)} (Δ {fmt(r['delta'], digits, True)}{ci})"


def _column(r) -> str:
    return UNPRUNED if r["method"] == UNPRUNED else f"prune {ratios.percent(r['ratio'])}"


def _sections(tidy: pd.DataFrame, mets) -> list[tuple[str, pd.DataFrame]]:
    out = []
    cols = [UNPRUNED] + [
        f"prune {ratios.percent(r)}" for r in sorted(set(tidy.loc[tidy["method"] != UNPRUNED, "ratio"]))
    ]
    for m in mets:
        t = tidy[tidy["metric"] == m]
        spec = catalog.METRICS.get(m)
        rows = list(dict.fromkeys(zip(t["label"], t["method_label"])))
        table = pd.DataFrame("", pd.MultiIndex.from_tuples(rows, names=["Dataset", "Method"]), cols)
        for _, r in t.iterrows():
            table.loc[(r["label"], r["method_label"]), _column(r)] = _text(r, spec.digits)
        out.append((spec.heading, table))
    return out


def _wide(tidy: pd.DataFrame, mets) -> pd.DataFrame:
    """Paper layout: rows (dataset, metric), columns (method, prune %) of means."""
    keys = list(dict.fromkeys(zip(tidy["method_label"], [_column(r) for _, r in tidy.iterrows()])))
    rows = [(lab, catalog.METRICS.get(m).heading) for lab in dict.fromkeys(tidy["label"]) for m in mets]
    disp = pd.DataFrame("–", pd.MultiIndex.from_tuples(rows, names=["Dataset", "Metric"]),
                        pd.MultiIndex.from_tuples(keys, names=["method", "prune"]))
    for _, r in tidy.iterrows():
        spec = catalog.METRICS.get(r["metric"])
        disp.loc[(r["label"], spec.heading), (r["method_label"], _column(r))] = fmt(r["mean"], spec.digits)
    return disp


def _notes(tidy: pd.DataFrame) -> list[str]:
    occ = tidy.drop_duplicates("scene")[["label", "occupancy"]]
    return ["renders against the captured photos of the held-out views (paper: \"against captured ground-truth "
            "images\"); Δ = pruned − unpruned against the same photo, paired per view [95 % percentile bootstrap "
            f"CI, {stats.N_RESAMPLES:,} resamples, seed {stats.SEED}]; every other table's plain metrics compare the "
            "pruned render with the unpruned one",
            "OM: over the pixels where the unpruned render's accumulated alpha ≥ 0.5 ("
            + ", ".join(f"{lab}: {o:.0f} % of the frame" for lab, o in zip(occ["label"], occ["occupancy"]))
            + "); a cropped scene's photo shows background its splats never held, which the full-frame "
              "numbers count against every method alike",
            "the cameras were aligned to the splats by a fitted similarity, and whether the model saw the held-out "
            "photos in training is unknown: absolute values against the photos depend on both, Δ much less"]
