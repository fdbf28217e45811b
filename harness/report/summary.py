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




#: the held-out view protocol of the training rig (harness.views.rigs.PROTOCOLS)
PRIMARY_PROTOCOL = "rig"
PROTOCOL_NOTES = {"rig": "held-out views of the rig the camera-aware methods train on",
                  "shifted": "held-out views from another camera distribution (higher rings, narrower field of "
                             "view, other azimuths) than the camera-aware methods' training views",
                  "independent": "random held-out views (positions, look-at jitter, fields of view, close-ups) "
                                 "defined independently of the training rig and of any virtual rig"}


def protocol_subsets(df: pd.DataFrame) -> list[tuple[str, str, pd.DataFrame]]:
    """(protocol, file-name suffix, its rows) per held-out view protocol of a run, the primary one
    first and unsuffixed (rows without a protocol — skips, errors — belong to every subset). A run
    with one protocol is one subset, as before protocols existed."""
    names = [p for p in dict.fromkeys(df["protocol"]) if p] if "protocol" in df else []
    if len(names) <= 1:
        return [(names[0] if names else "", "", df)]
    primary = PRIMARY_PROTOCOL if PRIMARY_PROTOCOL in names else names[0]
    order = [primary] + sorted(n for n in names if n != primary)
    return [(n, "" if n == primary else f"-{n}", df[df["protocol"].isin([n, ""])]) for n in order]
