"""Per-cell summaries of tidy results: one row per (scene, method, variant, ratio)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from harness.report.results import EXTRA_METRICS


def summarise(df: pd.DataFrame) -> pd.DataFrame:
    """Per (scene, label, method, variant, ratio): ``n`` views, ``n_inf``, ``frames``; the mean of
    psnr (finite values), ssim, lpips, the MPEG metrics and occupancy where the rows have them, each
    with its sample standard deviation ``<metric>_std`` (ddof = 1, over the same values; NaN below
    two) as ns-eval writes ``psnr_std``; ``score_s`` (mean over frames, ``score_s_std``),
    ``splats_in``, and the means of ``splats_out`` and ``bytes``."""
    ok = df[df["status"] == "ok"].copy()
    cols = ["scene", "label", "method", "variant", "ratio"]
    if ok.empty:
        return pd.DataFrame(columns=cols + ["n", "n_inf", "frames", "psnr", "psnr_std", "ssim", "ssim_std", "lpips",
                                            "lpips_std", "score_s", "score_s_std", "splats_in"])
    ok["psnr_f"] = ok["psnr"].where(np.isfinite(ok["psnr"]))
    ok["is_inf"] = np.isinf(ok["psnr"])
    g = ok.groupby(cols, sort=False, dropna=False)
    per_frame = ok.groupby(cols + ["frame"], sort=False, dropna=False)["score_s"].first().groupby(cols, sort=False)
    out = pd.DataFrame({
        "n": g.size(), "n_inf": g["is_inf"].sum().astype(int), "frames": g["frame"].nunique(),
        "psnr": g["psnr_f"].mean(), "psnr_std": g["psnr_f"].std(ddof=1),
        "ssim": g["ssim"].mean(), "ssim_std": g["ssim"].std(ddof=1),
        "lpips": g["lpips"].mean(), "lpips_std": g["lpips"].std(ddof=1),
        "score_s": per_frame.mean(), "score_s_std": per_frame.std(ddof=1),
        "splats_in": g["splats_in"].max(),
    }).reset_index()
    for c in EXTRA_METRICS + ["splats_out", "bytes"]:  # MPEG metrics are capped (never inf): plain means
        if c in ok:
            vals = pd.to_numeric(ok[c], errors="coerce").groupby([ok[k] for k in cols], sort=False, dropna=False)
            out[c] = vals.mean().to_numpy()
            if c in EXTRA_METRICS:
                out[f"{c}_std"] = vals.std(ddof=1).to_numpy()
    all_inf = (out["n_inf"] == out["n"]) & (out["n"] > 0)
    out.loc[all_inf, "psnr"] = np.inf
    return out


#: the held-out view protocol of the training rig (harness.views.rigs.PROTOCOLS)
PRIMARY_PROTOCOL = "rig"
PROTOCOL_NOTES = {"rig": "held-out views of the rig the camera-aware methods train on",
                  "shifted": "held-out views from another camera distribution (higher rings, narrower field of "
                             "view, other azimuths) than the camera-aware methods' training views",
                  "real": "the real capture's held-out cameras; camera-aware methods train on its training cameras; "
                          "'vs photo' metrics compare with the captured photos, the others with the unpruned render",
                  "independent": "random held-out views (positions, look-at jitter, fields of view, close-ups) "
                                 "defined independently of the training rig and of any virtual rig"}


def protocol_subsets(df: pd.DataFrame) -> list[tuple[str, str, pd.DataFrame]]:
    """(protocol, file-name suffix, its rows) per held-out view protocol of a run, the primary one
    first and unsuffixed (rows without a protocol — skips, errors — belong to every subset). Results
    that carry no protocol (from before protocols existed) are one subset named ""."""
    names = [p for p in dict.fromkeys(df["protocol"]) if p] if "protocol" in df else []
    if not names:
        return [("", "", df)]
    primary = PRIMARY_PROTOCOL if PRIMARY_PROTOCOL in names else names[0]
    order = [primary] + sorted(n for n in names if n != primary)
    return [(n, "" if n == primary else f"-{n}", df[df["protocol"].isin([n, ""])]) for n in order]
