"""Plots of a run (matplotlib, Agg): quality-vs-ratio curves and the paper's image grids.

* ``curves``: per scene, PSNR and LPIPS vs pruning ratio, one line per method's default variant
  (PSNR means exclude +inf pairs); ``plots/curves_<scene>.png``.
* ``figure1`` (paper Fig. 1): per scene, the unpruned render and the paper's method (the full cell
  of the registry's ablation grid) at τ-quantile 0.1/0.3/0.5/0.7 (ratio = removed fraction), first
  held-out view; ``plots/figure1.png``.
* ``figure3`` (paper Fig. 3): per scene, input, the method without Beta ("No Beta") and with it
  ("Beta") at 20 %; ``plots/figure3.png``.

Image grids read the renders the run stored under ``<run>/images/`` (no rendering here).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from harness.report import catalog
from harness.report.record import _slug, image_name
from harness.report.summary import summarise

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


def plot_curves(df: pd.DataFrame, out: Path) -> list[Path]:
    plt = _plt()
    s = summarise(df)
    s = s[s["variant"] == "default"]
    paths = []
    for scene, d in s.groupby("label", sort=False):
        fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
        for method, m in d.groupby("method", sort=True):
            m = m.sort_values("ratio")
            for ax, key in zip(axes, ("psnr", "lpips")):
                y = m[key].replace(np.inf, np.nan)
                ax.plot(100 * m["ratio"], y, marker="o", label=catalog.method_label(method))
        for ax, name in zip(axes, ("PSNR (dB, ↑)", "LPIPS-VGG (↓)")):
            ax.set_xlabel("pruning ratio (%)")
            ax.set_ylabel(name)
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize=7)
        fig.suptitle(f"{scene}: pruned vs unpruned render, held-out views")
        paths.append(_save(fig, out / f"curves_{_slug(scene)}.png"))
        plt.close(fig)
    return paths


def _first_frame_dir(images: Path, scene: str) -> Path | None:
    d = images / _slug(scene)
    if (d / "input.png").exists():
        return d
    subs = sorted(p for p in d.glob("*") if p.is_dir()) if d.exists() else []
    return subs[0] if subs else None


def _grid(df: pd.DataFrame, images: Path, columns, title: str, path: Path) -> list[Path]:
    """Rows = scenes with at least one image; ``columns`` = [(header, method, variant, ratio)]."""
    from PIL import Image

    plt = _plt()
    scenes = [(label, name) for name, label in dict.fromkeys(zip(df["scene"], df["label"]))]
    rows = []
    for label, name in scenes:
        d = _first_frame_dir(images, name)
        if d is None:
            continue
        files = [d / image_name(m, v, r) for _, m, v, r in columns]
        if sum(f.exists() for f in files) > 1:
            rows.append((label, files))
    if not rows:
        return []
    fig, axes = plt.subplots(len(rows), len(columns), figsize=(2.6 * len(columns), 2.2 * len(rows)), squeeze=False)
    for i, (label, files) in enumerate(rows):
        for j, f in enumerate(files):
            ax = axes[i, j]
            ax.set_xticks([])
            ax.set_yticks([])
            if f.exists():
                ax.imshow(np.asarray(Image.open(f).convert("RGB")))
            else:
                ax.text(0.5, 0.5, "not run", ha="center", va="center", transform=ax.transAxes)
            if i == 0:
                ax.set_title(columns[j][0], fontsize=9)
            if j == 0:
                ax.set_ylabel(label, fontsize=9)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out = _save(fig, path)
    plt.close(fig)
    return [out]


def write_plots(df: pd.DataFrame, run_dir: str | Path, names) -> list[Path]:
    run_dir = Path(run_dir)
    out = run_dir / "plots"
    images = run_dir / "images"
    written: list[Path] = []
    if "curves" in names:
        written += plot_curves(df, out)
    proposed = catalog.proposed_method()
    if "figure1" in names and proposed:
        cols = [("unpruned", "input", "", 0.0)] + [(f"τ ≈ {r:g} ({100 * r:.0f} % pruned)", proposed, "default", r)
                                                   for r in FIG1_RATIOS]
        title = f"{catalog.method_label(proposed)} at increasing pruning (paper Fig. 1)"
        written += _grid(df, images, cols, title, out / "figure1.png")
    pair = catalog.beta_pair()
    if "figure3" in names and pair:
        cols = [("input", "input", "", 0.0), ("No Beta", pair[0], "default", FIG3_RATIO),
                ("Beta", pair[1], "default", FIG3_RATIO)]
        written += _grid(df, images, cols, "No Beta vs Beta at 20 % pruning (paper Fig. 3)", out / "figure3.png")
    return written
