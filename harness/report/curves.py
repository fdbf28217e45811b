"""The ``curves`` plot: per scene, quality against the pruning ratio, one line per method's default variant.

Panels, from the metric registry: the first dB metric the results carry (PSNR), its
occupancy-masked variant when present, the first lower-is-better metric (LPIPS), and — when the
results carry ``bytes`` — the dB metric against the pruned file's size; ``plots/curves_<scene>.png``.
Points are cell means (:func:`harness.report.stats.summary`: dB means leave near-identical views
out). A cell whose views are *all* near-identical (≥ 100 dB / inf) has no informative mean: it is
drawn as a ▲ on the top edge of the axis, which spans the informative values only, so one 197 dB
point no longer stretches the axis. The legend sits outside the axes, right of the panels.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from harness.report import catalog, drawing, stats
from harness.report.cells import prepare
from harness.report.record import slug


def curve_metrics(mets) -> list[tuple[str, str, int]]:
    """The curves' panels among the shown metrics: first dB metric, its OM variant, first lower-is-better."""
    db = [m for m in mets if stats.is_db(m[0])]
    out = db[:1]
    if db:
        out += [m for m in db if m[0] != db[0][0] and catalog.masked_of(m[0]) == db[0][0]][:1]
    out += [m for m in mets if not catalog.higher_is_better(m[0])][:1]
    return out


def cell_points(ok: pd.DataFrame, mets) -> pd.DataFrame:
    """Per (scene, method, ratio) of default variants: mean of each metric, whether every view is
    near-identical, mean bytes when present."""
    d = ok[ok["variant"] == "default"]
    rows = []
    for (scene, method, r), g in d.groupby(["scene", "method", "rkey"], sort=False):
        row = {"scene": scene, "label": g["label"].iloc[0], "method": method, "ratio": r,
               "all_near": bool(g["near"].all())}
        for m, *_ in mets:
            row[m] = stats.summary(g[m], g["near"], m)["mean"]
        if "bytes" in g and g["bytes"].notna().any():
            row["bytes"] = float(pd.to_numeric(g["bytes"], errors="coerce").mean())
        rows.append(row)
    return pd.DataFrame(rows)


def _panel(ax, pts: pd.DataFrame, metric: str, heading: str, x: str, colors: dict) -> None:
    top_marks = []
    for method, m in pts.groupby("method", sort=False):
        m = m.sort_values(x)
        y = m[metric].to_numpy(dtype=float)
        ax.plot(m[x], y, marker="o", ms=4, color=colors[method], label=catalog.method_label(method))
        if stats.is_db(metric):
            top_marks += [(xv, colors[method]) for xv, near, yv in zip(m[x], m["all_near"], y) if near and np.isnan(yv)]
    if top_marks:
        trans = ax.get_xaxis_transform()
        span = np.ptp(pts[x].to_numpy(dtype=float)) or 1.0
        by_x: dict = {}
        for xv, c in top_marks:
            by_x.setdefault(xv, []).append(c)
        for xv, cs in by_x.items():  # side by side where several methods share a ratio
            for k, c in enumerate(cs):
                ax.plot([xv + (k - (len(cs) - 1) / 2) * 0.025 * span], [0.96], marker="^", ms=8, color=c,
                        transform=trans, clip_on=False, ls="none")
        lo, hi = ax.get_ylim()
        ax.set_ylim(lo, hi + 0.1 * (hi - lo))
    ax.set_ylabel(heading)
    ax.grid(alpha=0.3)


def plot_curves(df: pd.DataFrame, out: Path, protocol: str = "") -> list[Path]:
    """``curves_<scene>.png`` per scene into ``out`` (module docstring); the files written."""
    plt = drawing.pyplot()
    ok, mets = prepare(df)
    panels = curve_metrics(mets)
    pts = cell_points(ok, mets)
    if pts.empty or not panels:
        return []
    order = catalog.method_order(pts["method"])
    cmap = plt.get_cmap("tab10")
    colors = {m: cmap(i % 10) for i, m in enumerate(order)}
    has_bytes = "bytes" in pts and pts["bytes"].notna().any()
    paths = []
    for scene, d in pts.groupby("label", sort=False):
        d = d.assign(pct=100 * d["ratio"], _o=d["method"].map(order.index)).sort_values("_o")
        n = len(panels) + bool(has_bytes)
        fig, axes = plt.subplots(1, n, figsize=(4.2 * n, 3.6), squeeze=False)
        for ax, (key, heading, _) in zip(axes[0], panels):
            _panel(ax, d, key, heading, "pct", colors)
            ax.set_xlabel("pruning ratio (%)")
        if has_bytes:
            ax = axes[0][-1]
            _panel(ax, d.dropna(subset=["bytes"]).assign(mib=lambda t: t["bytes"] / 2**20), panels[0][0],
                   panels[0][1], "mib", colors)
            ax.set_xlabel("pruned .ply size (MiB)")
        handles, labels = axes[0][0].get_legend_handles_labels()
        if d["all_near"].any():
            from matplotlib.lines import Line2D

            handles.append(Line2D([], [], marker="^", ms=8, color="0.35", ls="none"))
            labels.append(
                f"every view ≥ {stats.NEAR_IDENTICAL_DB:g} dB\n(near-identical; off the\nscale, at the top edge)"
            )
        fig.legend(handles, labels, loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=8, frameon=False)
        views = f"held-out views: {protocol}" if protocol else "held-out views"
        fig.suptitle(f"{scene}: pruned vs unpruned render, {views} (cell means)")
        fig.tight_layout()
        paths.append(drawing.save(fig, out / f"curves_{slug(scene)}.png"))
        plt.close(fig)
    return paths
