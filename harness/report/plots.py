"""Plots of a run (matplotlib, Agg): quality-vs-ratio curves and the paper's image grids.

* ``curves``: per scene, quality vs pruning ratio, one line per method's default variant: the first
  dB metric the results carry (PSNR), its occupancy-masked variant when present, the first
  lower-is-better metric (LPIPS), and — when the results carry ``bytes`` — the dB metric against the
  pruned file's size; ``plots/curves_<scene>.png``. Points are cell means
  (:func:`harness.report.stats.summary`: dB means leave near-identical views out). A cell whose
  views are *all* near-identical (≥ 100 dB / inf) has no informative mean: it is drawn as a ▲ on the
  top edge of the axis, which spans the informative values only, so one 197 dB point no longer
  stretches the axis. The legend sits outside the axes, right of the panels.
* ``figure1`` (paper Fig. 1): per scene, the unpruned render and the paper's method (the full cell
  of the registry's ablation grid) at 10/30/50/70 % pruning, first held-out view; column titles give
  the ratio and the range of the actual τ (score at the cut, results' ``tau``) over the scenes, each
  image its own τ. ``plots/figure1.png``.
* ``figure3`` (paper Fig. 3): per scene, input, the method without Beta ("No Beta") and with it
  ("Beta") at 20 %; ``plots/figure3.png``.

Image grids read the renders the run stored under ``<run>/images/`` (no rendering here); a column
that no scene has (e.g. 50 / 70 % in a run of 10–30 %) is left out, and a cell one scene lacks is
blank. A plot that cannot be drawn is named in the returned
:class:`~harness.report.tabledata.Written` with why.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.report import catalog, stats
from harness.report.cells import prepare
from harness.report.record import image_name, slug
from harness.report.tabledata import Written

#: the plots a config or ``harness tables --plots`` can name
PLOTS = ("curves", "figure1", "figure3", "photos")
FIG1_RATIOS = (0.1, 0.3, 0.5, 0.7)
FIG3_RATIO = 0.2


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    from harness.io.files import atomic_write_with

    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_with(path, lambda p: fig.savefig(p, dpi=110, bbox_inches="tight", format="png"))
    return path


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
    plt = _plt()
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
        paths.append(_save(fig, out / f"curves_{slug(scene)}.png"))
        plt.close(fig)
    return paths


def _first_frame_dir(images: Path, scene: str) -> Path | None:
    d = images / slug(scene)
    if (d / "input.png").exists():
        return d
    subs = sorted(p for p in d.glob("*") if p.is_dir()) if d.exists() else []
    return subs[0] if subs else None


def _grid(df: pd.DataFrame, images: Path, columns, title: str, path: Path, caption=None) -> list[Path]:
    """Rows = scenes with at least two images; ``columns`` = [(header, method, variant, ratio)];
    ``caption(scene, column)`` -> text under an image (or "")."""
    from harness.io.safe import open_image

    plt = _plt()
    scenes = [(label, name) for name, label in dict.fromkeys(zip(df["scene"], df["label"]))]
    rows = []
    for label, name in scenes:
        d = _first_frame_dir(images, name)
        if d is None:
            continue
        files = [d / image_name(m, v, r) for _, m, v, r in columns]
        if sum(f.exists() for f in files) > 1:
            rows.append((label, name, files))
    present = [j for j in range(len(columns)) if any(files[j].exists() for _, _, files in rows)]
    columns = [columns[j] for j in present]
    rows = [(label, name, [files[j] for j in present]) for label, name, files in rows]
    if not rows:
        return []
    fig, axes = plt.subplots(len(rows), len(columns), figsize=(2.6 * len(columns), 2.35 * len(rows)), squeeze=False)
    for i, (label, name, files) in enumerate(rows):
        for j, f in enumerate(files):
            ax = axes[i, j]
            ax.set_xticks([])
            ax.set_yticks([])
            if f.exists():
                ax.imshow(np.asarray(open_image(f, "run image")))  # bounded read (harness.io.safe)
            else:  # this scene lacks the cell: a blank panel, no frame
                ax.set_frame_on(False)
            if i == 0:
                ax.set_title(columns[j][0], fontsize=9)
            if j == 0:
                ax.set_ylabel(label, fontsize=9)
            text = caption(name, columns[j]) if caption else ""
            if text:
                ax.set_xlabel(text, fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out = _save(fig, path)
    plt.close(fig)
    return [out]


def _taus(df: pd.DataFrame, method: str) -> dict:
    """(scene, ratio key) -> τ of the first frame (score at the cut)."""
    d = df[(df["method"] == method) & (df["variant"] == "default") & df["tau"].notna()]
    return {(s, ratios.key(r)): float(t) for (s, r), t in d.groupby(["scene", "ratio"])["tau"].first().items()}


def write_plots(df: pd.DataFrame, run_dir: str | Path, names) -> Written:
    """The plots of the primary held-out view protocol (the training rig's views), which their
    titles name."""
    from harness.report.summary import protocol_subsets

    run_dir = Path(run_dir)
    w = Written()
    if "photos" in names:  # the captured views' figure (harness.report.photofigure): its own protocol's rows
        from harness.report.photofigure import write_photo_figures

        w.paths += (got := write_photo_figures(df, run_dir))
        if not got:
            w.missing.append("plot photos not drawn: no stored render of a view with a captured photo "
                             "(scenes with a capture, under the `real` protocol)")
    protocol, _, df = protocol_subsets(df)[0]
    first_view = f" — first held-out view ({protocol})" if protocol else ""
    out = run_dir / "plots"
    images = run_dir / "images"
    if "curves" in names:
        got = plot_curves(df, out, protocol)
        w.paths += got
        if not got:
            w.missing.append("plot curves not drawn: no measured default variant")
    proposed = catalog.proposed_method()
    if "figure1" in names:
        got = []
        if proposed:
            taus = _taus(df, proposed)
            cols = [("unpruned", "input", "", 0.0)]
            for r in FIG1_RATIOS:
                tv = [t for (_, rk), t in taus.items() if rk == ratios.key(r)]
                rng = (
                    "" if not tv else f"\nτ = {min(tv):.3f}" + (f"–{max(tv):.3f}" if max(tv) - min(tv) >= 5e-4 else "")
                )
                cols.append((f"{ratios.percent(r)} pruned{rng}", proposed, "default", r))

            def cap(scene, col):
                t = taus.get((scene, ratios.key(col[3])))
                return "" if col[1] == "input" or t is None else f"τ = {t:.3f}"

            title = (f"{catalog.method_label(proposed)} at increasing pruning, τ = score at the cut (paper Fig. 1)"
                     + first_view)
            got = _grid(df, images, cols, title, out / "figure1.png", cap)
        w.paths += got
        if not got:
            w.missing.append(f"plot figure1 not drawn: no stored render of {proposed or 'the proposed method'} at "
                             f"{' / '.join(ratios.percent(r) for r in FIG1_RATIOS)} beside an unpruned one in {images}")
    pair = catalog.beta_pair()
    if "figure3" in names:
        got = []
        if pair:
            cols = [("input", "input", "", 0.0), ("No Beta", pair[0], "default", FIG3_RATIO),
                    ("Beta", pair[1], "default", FIG3_RATIO)]
            got = _grid(df, images, cols, "No Beta vs Beta at 20 % pruning (paper Fig. 3)" + first_view,
                        out / "figure3.png")
        w.paths += got
        if not got:
            w.missing.append(f"plot figure3 not drawn: no stored renders of {' and '.join(pair or ('the Beta pair',))} "
                             f"at {ratios.percent(FIG3_RATIO)} in {images}")
    return w
