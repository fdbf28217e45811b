"""``plots/photos-<scene>.png``: a held-out view with a photo (the ``real`` protocol's) as photo | unpruned | pruned.

From the images a run keeps of its first captured view (``images/<scene>[/<frame>]/real/``:
``photo.png`` — the photo area-averaged to the render size —, ``input.png`` — the unpruned render —
and one pruned render per method × ratio), at their own pixel size (no resampling): the first row
is the photo, the unpruned render and the proposed method; the other comparison methods follow,
three panels a row, all at the highest measured ratio of 10/20/30 %. Each caption gives the panel's
PSNR against the photo and, for a pruned render, against the unpruned render (the view's row of
the results). The report page shows these files with the other figures.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.report import catalog
from harness.report.record import image_name, slug

COLUMNS = 3
PAD = 6
CAPTION = 48  # px of caption under each panel (title + two lines)
MIN_WIDTH = 300  # smaller renders are shown enlarged (nearest neighbour, whole factors) so captions fit
LEVELS = (0.3, 0.2, 0.1)



def _font(size: int):
    """DejaVu Sans (matplotlib's own, so labels such as "ConfSplatPrune — lower bound" keep their
    dash; Pillow's default font has no "—"), else Pillow's default."""
    from PIL import ImageFont

    try:
        from matplotlib import font_manager

        return ImageFont.truetype(font_manager.findfont("DejaVu Sans", fallback_to_default=True), size)
    except (ImportError, OSError, ValueError):
        return ImageFont.load_default(size=size)

def _real_dir(images: Path, scene: str, protocol: str) -> Path | None:
    """The folder of the scene's first captured view: ``<scene>[/<frame>]/<protocol>``, or the scene's
    (first frame's) own folder when that protocol was the run's primary one."""
    d = images / slug(scene)
    frames = sorted(p for p in d.glob("*") if p.is_dir() and p.name != protocol) if d.exists() else []
    for cand in (c for f in (d, *frames) for c in (f / protocol, f)):
        if (cand / "photo.png").is_file() and (cand / "input.png").is_file():
            return cand
    return None


def _panels(df: pd.DataFrame, scene: str, d: Path, ratio: float) -> list[tuple[Path, str, str]]:
    """(image, title, caption) of each panel."""
    rows = df[(df["scene"] == scene) & (df["status"] == "ok") & df["gt_psnr"].notna()]
    view = sorted(rows["view"])[0]
    rows = rows[rows["view"] == view]
    unpruned = rows["unpruned_gt_psnr"].iloc[0]
    out = [(d / "photo.png", f"photo {view.split('/', 1)[-1]}", "captured, area-averaged\nto the render size"),
           (d / "input.png", "unpruned", f"vs photo {unpruned:.2f} dB")]
    proposed = catalog.proposed_method()
    methods = [m for _, m in catalog.comparison_methods(rows["method"])]
    for m in sorted(methods, key=lambda m: m != proposed):
        r = rows[(rows["method"] == m) & (rows["variant"] == "default") & ((rows["ratio"] - ratio).abs() < 1e-9)]
        f = d / image_name(m, "default", ratio)
        if len(r) and f.is_file():
            x = r.iloc[0]
            psnr = "inf" if np.isinf(x["psnr"]) else f"{x['psnr']:.2f}"
            out.append((f, f"{catalog.method_label(m)}, {ratios.percent(ratio)} pruned",
                        f"vs photo {x['gt_psnr']:.2f} dB\nvs unpruned {psnr} dB"))
    return out


def write_photo_figures(df: pd.DataFrame, run_dir: str | Path) -> list[Path]:
    """One figure per scene with a stored captured view (of the protocol whose rows carry the photo
    metrics); returns the files written."""
    from PIL import Image, ImageDraw

    from harness.io.files import atomic_write_with

    run_dir = Path(run_dir)
    if "gt_psnr" not in df or df["gt_psnr"].isna().all():
        return []
    out = []
    for scene in dict.fromkeys(df.loc[df["gt_psnr"].notna(), "scene"]):
        sub = df[(df["scene"] == scene) & df["gt_psnr"].notna()]
        protocol = str(sub["protocol"].iloc[0]) if "protocol" in sub and len(sub) else ""
        d = _real_dir(run_dir / "images", scene, protocol)
        ratio = next((r for r in LEVELS if ((sub["ratio"] - r).abs() < 1e-9).any()), None)
        if d is None or ratio is None:
            continue
        panels = _panels(df, scene, d, ratio)
        imgs = [Image.open(f).convert("RGB") for f, _, _ in panels]
        k = -(-MIN_WIDTH // imgs[0].width)
        w, h = imgs[0].width * k, imgs[0].height * k
        n_rows = -(-len(imgs) // COLUMNS)
        sheet = Image.new("RGB", (COLUMNS * (w + PAD) + PAD, 24 + n_rows * (h + CAPTION + PAD)), "white")
        draw = ImageDraw.Draw(sheet)
        font, small = _font(13), _font(11)
        label = df.loc[df["scene"] == scene, "label"].iloc[0]
        draw.text((PAD, 5), f"{label}: a held-out view of the real capture (photo | unpruned | pruned"
                            + (f", shown {k}x enlarged)" if k > 1 else ")"), fill="black", font=font)
        for k, (img, (_, title, caption)) in enumerate(zip(imgs, panels)):
            x, y = PAD + (k % COLUMNS) * (w + PAD), 24 + (k // COLUMNS) * (h + CAPTION + PAD)
            sheet.paste(img.resize((w, h), Image.Resampling.NEAREST) if img.size != (w, h) else img, (x, y))
            draw.text((x, y + h + 2), title, fill="black", font=font)
            draw.multiline_text((x, y + h + 18), caption, fill="#333333", font=small, spacing=2)
        path = run_dir / "plots" / f"photos-{slug(scene)}.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_with(path, lambda p, s=sheet: s.save(p, format="PNG"))
        out.append(path)
    return out
