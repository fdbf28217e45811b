"""The paper's image grids of a run: ``figure1`` (Fig. 1) and ``figure3`` (Fig. 3).

* ``figure1``: per scene, the unpruned render and the paper's method (the full cell of the
  registry's ablation grid) at 10/30/50/70 % pruning, first held-out view; column titles give the
  ratio and the range of the actual τ (score at the cut, results' ``tau``) over the scenes, each
  image its own τ. ``plots/figure1.png``.
* ``figure3``: per scene, input, the method without Beta ("No Beta") and with it ("Beta") at 20 %;
  ``plots/figure3.png``.

They read the renders the run stored under ``<run>/images/`` (no rendering here); a column that no
scene has (e.g. 50 / 70 % in a run of 10–30 %) is left out, and a cell one scene lacks is blank.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.report import catalog, drawing
from harness.report.record import image_name, slug
from harness.report.tabledata import Missing

FIG1_RATIOS = (0.1, 0.3, 0.5, 0.7)
FIG3_RATIO = 0.2


def _first_frame_dir(images: Path, scene: str) -> Path | None:
    d = images / slug(scene)
    if (d / "input.png").exists():
        return d
    subs = sorted(p for p in d.glob("*") if p.is_dir()) if d.exists() else []
    return subs[0] if subs else None


def _grid_rows(df: pd.DataFrame, images: Path, columns) -> tuple[list, list]:
    """(the columns some scene has, [(label, scene, files)] of the scenes with at least two images)."""
    scenes = [(label, name) for name, label in dict.fromkeys(zip(df["scene"], df["label"]))]
    rows = []
    for label, name in scenes:
        d = _first_frame_dir(images, name)
        files = [] if d is None else [d / image_name(m, v, r) for _, m, v, r in columns]
        if sum(f.exists() for f in files) > 1:
            rows.append((label, name, files))
    present = [j for j in range(len(columns)) if any(files[j].exists() for _, _, files in rows)]
    return [columns[j] for j in present], [(label, name, [files[j] for j in present]) for label, name, files in rows]


def _grid(df: pd.DataFrame, images: Path, columns, title: str, path: Path, caption=None) -> list[Path]:
    """Rows = scenes with at least two images; ``columns`` = [(header, method, variant, ratio)];
    ``caption(scene, column)`` -> text under an image (or "")."""
    plt = drawing.pyplot()
    columns, rows = _grid_rows(df, images, columns)
    if not rows:
        return []
    fig, axes = plt.subplots(len(rows), len(columns), figsize=(2.6 * len(columns), 2.35 * len(rows)), squeeze=False)
    for i, (label, name, files) in enumerate(rows):
        for j, f in enumerate(files):
            _panel(axes[i, j], f, columns[j][0] if i == 0 else "", label if j == 0 else "",
                   caption(name, columns[j]) if caption else "")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out = drawing.save(fig, path)
    plt.close(fig)
    return [out]


def _panel(ax, image: Path, title: str, ylabel: str, xlabel: str) -> None:
    """One cell of a grid: the image (a blank panel without a frame where the scene lacks it) and its texts."""
    from harness.io.safe import open_image

    ax.set_xticks([])
    ax.set_yticks([])
    if image.exists():
        ax.imshow(np.asarray(open_image(image, "run image")))  # bounded read (harness.io.safe)
    else:
        ax.set_frame_on(False)
    if title:
        ax.set_title(title, fontsize=9)
    if ylabel:
        ax.set_ylabel(ylabel, fontsize=9)
    if xlabel:
        ax.set_xlabel(xlabel, fontsize=8)


def _taus(df: pd.DataFrame, method: str) -> dict:
    """(scene, ratio key) -> τ of the first frame (score at the cut)."""
    d = df[(df["method"] == method) & (df["variant"] == "default") & df["tau"].notna()]
    return {(s, ratios.key(r)): float(t) for (s, r), t in d.groupby(["scene", "ratio"])["tau"].first().items()}


def draw_figure1(df: pd.DataFrame, ctx) -> list[Path] | Missing:
    """Figure 1 (module docstring) into ``ctx.out``."""
    proposed = catalog.proposed_method()
    if proposed:
        taus = _taus(df, proposed)
        cols = [("unpruned", "input", "", 0.0)]
        for r in FIG1_RATIOS:
            tv = [t for (_, rk), t in taus.items() if rk == ratios.key(r)]
            rng = "" if not tv else f"\nτ = {min(tv):.3f}" + (f"–{max(tv):.3f}" if max(tv) - min(tv) >= 5e-4 else "")
            cols.append((f"{ratios.percent(r)} pruned{rng}", proposed, "default", r))

        def cap(scene, col):
            t = taus.get((scene, ratios.key(col[3])))
            return "" if col[1] == "input" or t is None else f"τ = {t:.3f}"

        title = (f"{catalog.method_label(proposed)} at increasing pruning, τ = score at the cut (paper Fig. 1)"
                 + ctx.first_view)
        got = _grid(df, ctx.images, cols, title, ctx.out / "figure1.png", cap)
        if got:
            return got
    return Missing(f"no stored render of {proposed or 'the proposed method'} at "
                   f"{' / '.join(ratios.percent(r) for r in FIG1_RATIOS)} beside an unpruned one in {ctx.images}")


def draw_figure3(df: pd.DataFrame, ctx) -> list[Path] | Missing:
    """Figure 3 (module docstring) into ``ctx.out``."""
    pair = catalog.beta_pair()
    if pair:
        cols = [("input", "input", "", 0.0), ("No Beta", pair[0], "default", FIG3_RATIO),
                ("Beta", pair[1], "default", FIG3_RATIO)]
        got = _grid(df, ctx.images, cols, "No Beta vs Beta at 20 % pruning (paper Fig. 3)" + ctx.first_view,
                    ctx.out / "figure3.png")
        if got:
            return got
    return Missing(f"no stored renders of {' and '.join(pair or ('the Beta pair',))} at "
                   f"{ratios.percent(FIG3_RATIO)} in {ctx.images}")
