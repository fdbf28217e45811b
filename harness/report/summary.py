"""Per-cell summaries of tidy results: one row per (scene, method, variant, ratio).

Which columns are metrics, and how each is averaged, the metric registry says
(:mod:`harness.metrics.registry`): a metric that is +inf on identical images
(``inf_if_identical``: PSNR) is averaged over its finite values and is +inf only when every view is;
any other metric is a plain mean (the MPEG PSNRs are capped, never infinite).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from harness.metrics import registry
from harness.report.results import metric_columns
from harness.views.protocols import PRIMARY

CELL = ["scene", "label", "method", "variant", "ratio"]


def _inf_metric(name: str) -> bool:
    s = registry.spec(name)
    return s is not None and s.inf_if_identical


def summarise(df: pd.DataFrame) -> pd.DataFrame:
    """Per (scene, label, method, variant, ratio): ``n`` views, ``frames``, ``n_inf`` (views whose first
    headline metric that can be +inf — PSNR — is); the mean of each headline metric (psnr, ssim,
    lpips), then ``score_s`` (mean over frames, ``score_s_std``) and ``splats_in``, then the mean of
    every other metric the rows carry (the MPEG set, the photo metrics, plugins', occupancy), each
    metric with its sample standard deviation ``<metric>_std`` (ddof = 1, over the same values; NaN
    below two) as ns-eval writes ``psnr_std``; and the means of ``splats_out`` and ``bytes``."""
    head = list(registry.headline())
    ok = df[df["status"] == "ok"].copy()
    if ok.empty:
        return pd.DataFrame(columns=CELL + ["n", "n_inf", "frames"] + [c for m in head for c in (m, f"{m}_std")]
                            + ["score_s", "score_s_std", "splats_in"])
    keys = [ok[k] for k in CELL]
    out = _counts_and_headline(ok, keys, head).reset_index()
    others = [c for c in metric_columns() if c not in head]
    for c in (c for c in others + ["splats_out", "bytes"] if c in ok):
        vals = _means(pd.to_numeric(ok[c], errors="coerce"), keys, _inf_metric(c))
        out[c] = vals.mean().to_numpy()
        if c in others:
            out[f"{c}_std"] = vals.std(ddof=1).to_numpy()
    for m in (m for m in metric_columns() if m in out and _inf_metric(m)):  # every view +inf: the mean is
        out.loc[_infinite(ok, m, keys).all().to_numpy(), m] = np.inf
    return out


def _counts_and_headline(ok: pd.DataFrame, keys, head: list[str]) -> pd.DataFrame:
    """The first columns of :func:`summarise`, indexed by the cell: counts, the headline metrics,
    the scoring time and the splats."""
    g = ok.groupby(CELL, sort=False, dropna=False)
    per_frame = ok.groupby(CELL + ["frame"], sort=False, dropna=False)["score_s"].first().groupby(CELL, sort=False)
    counted = next((m for m in head if _inf_metric(m) and m in ok), None)
    out = pd.DataFrame({"n": g.size(), "frames": g["frame"].nunique()})
    out.insert(1, "n_inf", _infinite(ok, counted, keys).sum().astype(int) if counted else 0)
    for m in (m for m in head if m in ok):
        means = _means(ok[m], keys, _inf_metric(m))
        out[m], out[f"{m}_std"] = means.mean(), means.std(ddof=1)
    out["score_s"], out["score_s_std"] = per_frame.mean(), per_frame.std(ddof=1)
    out["splats_in"] = g["splats_in"].max()
    return out


def _infinite(ok: pd.DataFrame, metric: str, keys):
    """Whether each row's ``metric`` is infinite, grouped by the cell ``keys``."""
    return pd.Series(np.isinf(pd.to_numeric(ok[metric], errors="coerce").to_numpy(np.float64)),
                     index=ok.index).groupby(keys, sort=False, dropna=False)


def _means(values: pd.Series, keys, finite_only: bool):
    """``values`` grouped by the cell ``keys`` (its finite values only with ``finite_only``)."""
    v = values.where(np.isfinite(values)) if finite_only else values
    return v.groupby(keys, sort=False, dropna=False)


#: the held-out view protocol of the training rig (:mod:`harness.views.heldout`)
PRIMARY_PROTOCOL = PRIMARY


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
