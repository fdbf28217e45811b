"""Per-cell summaries of tidy results: one row per (scene, method, variant, ratio)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from harness.report.results import EXTRA_METRICS


def summarise(df: pd.DataFrame) -> pd.DataFrame:
    """Per (scene, label, method, variant, ratio): n pairs, n_inf, mean psnr (finite), ssim, lpips, score_s,
    and the means of the MPEG metrics, occupancy, splats_out and bytes where the rows have them."""
    ok = df[df["status"] == "ok"].copy()
    cols = ["scene", "label", "method", "variant", "ratio"]
    if ok.empty:
        return pd.DataFrame(columns=cols + ["n", "n_inf", "psnr", "ssim", "lpips", "score_s", "splats_in"])
    ok["psnr_f"] = ok["psnr"].where(np.isfinite(ok["psnr"]))
    ok["is_inf"] = np.isinf(ok["psnr"])
    g = ok.groupby(cols, sort=False, dropna=False)
    out = pd.DataFrame({
        "n": g.size(), "n_inf": g["is_inf"].sum().astype(int), "psnr": g["psnr_f"].mean(),
        "ssim": g["ssim"].mean(), "lpips": g["lpips"].mean(),
        "score_s": g["score_s"].mean(),  # repeated on every view row of a frame: = mean over frames
        "splats_in": g["splats_in"].max(),
    }).reset_index()
    for c in EXTRA_METRICS + ["splats_out", "bytes"]:  # MPEG metrics are capped (never inf): plain means
        if c in ok:
            out[c] = pd.to_numeric(g[c].mean(), errors="coerce").to_numpy()
    all_inf = (out["n_inf"] == out["n"]) & (out["n"] > 0)
    out.loc[all_inf, "psnr"] = np.inf
    return out


