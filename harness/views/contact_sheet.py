"""Contact sheet: one PNG grid of rendered views, each labelled with its name and coverage.

**Coverage** of a view rendered over background colour b is the fraction of its pixels that show
content: with an alpha image (accumulated opacity 1 − T_final) a pixel counts when its alpha exceeds
``threshold``; from colour alone (what :meth:`render` returns) it counts when any channel differs
from b by more than ``threshold`` (default 1/255, one 8-bit step). Colour-only coverage misses
content whose colour equals the background (pure black splats over a black background), so it is
a lower bound of the alpha coverage; render over a contrasting background when that matters.

Thumbnails show the image clamped to [0, 1] and quantised to 8 bits as-is (no tone mapping), the same
as the renderer's PNG output.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

LABEL_HEIGHT = 18
GAP = 4


def coverage(image: np.ndarray, background=(0.0, 0.0, 0.0), *, alpha: np.ndarray | None = None,
             threshold: float = 1.0 / 255.0) -> float:
    """Fraction of pixels showing content (module docstring): in [0, 1]. A channel's NaN leaves its
    pixel uncounted (the pixel's largest difference is NaN)."""
    if alpha is not None:
        return float(np.mean(np.asarray(alpha) > threshold))
    img = np.asarray(image, np.float32)
    bg = np.asarray(background, np.float32).reshape(3)
    # the largest of the three channels' differences, channel against channel (an order of magnitude
    # faster than a max over the last axis, same values); the fraction is an exact count over the size
    diff = np.abs(img[..., 0] - bg[0])
    for c in (1, 2):
        np.maximum(diff, np.abs(img[..., c] - bg[c]), out=diff)
    return np.count_nonzero(diff > threshold) / diff.size


#: PNG compression of renders and sheets: zlib level 1 (lossless like every level; files ~25 % larger
#: than PIL's default 6, written in ~60 % of its time)
PNG_LEVEL = 1


def to_uint8(image: np.ndarray) -> np.ndarray:
    """Clamp to [0, 1] and quantise (round half up) to uint8, no gamma: the PNG encoding. NaN → 0,
    +inf → 255, −inf → 0 (``fmax``/``fmin`` take the number where one side is NaN)."""
    x = np.fmax(np.asarray(image, np.float32), np.float32(0.0))
    np.fmin(x, np.float32(1.0), out=x)
    x *= np.float32(255.0)
    x += np.float32(0.5)
    return x.astype(np.uint8)


def _thumbnail(pixels: np.ndarray, longest: int) -> Image.Image:
    """``pixels`` (uint8, :func:`to_uint8`) shrunk to ``longest`` px on the long side (Lanczos)."""
    im = Image.fromarray(pixels)
    s = longest / max(im.size)
    if s < 1:
        im = im.resize((max(1, round(im.width * s)), max(1, round(im.height * s))), Image.Resampling.LANCZOS)
    return im


#: the widest a sheet gets (px): many views get smaller thumbnails, so a sheet of 1,000 views stays
#: a few tens of megapixels
MAX_SHEET_SIDE = 8192


class ContactSheet:
    """A contact sheet built one view at a time: ``add(image, label)`` keeps only the view's
    thumbnail and coverage (the image itself can be dropped at once: a caller rendering N views
    holds one full image, not N), ``write(path)`` draws the grid. ``n`` views are expected, which
    sets the columns and a thumbnail size that keeps the sheet within :data:`MAX_SHEET_SIDE`."""

    def __init__(self, n: int, *, background=(0.0, 0.0, 0.0), thumb_longest: int = 320, columns: int | None = None):
        if n < 1:
            raise ValueError("a contact sheet needs at least one view")
        self.cols = max(1, min(columns or math.ceil(math.sqrt(n) * 1.2), n))
        self.thumb_longest = min(thumb_longest, max(32, MAX_SHEET_SIDE // self.cols - GAP))
        self.background = background
        self.thumbs: list[Image.Image] = []
        self.labels: list[str] = []
        self.covs: list[float] = []

    def add(self, image: np.ndarray, label: str, *, pixels: np.ndarray | None = None) -> float:
        """Keep the view's thumbnail and label; returns its coverage. ``pixels``: the image's
        :func:`to_uint8` when the caller has it already (its PNG)."""
        cov = coverage(image, self.background)
        self.thumbs.append(_thumbnail(to_uint8(image) if pixels is None else pixels, self.thumb_longest))
        self.labels.append(label)
        self.covs.append(cov)
        return cov

    def write(self, path: str | Path) -> list[float]:
        """Write the grid PNG atomically; returns every view's coverage (labels get `` cov xx.x%``)."""
        if not self.thumbs:
            raise ValueError("need at least one image")
        thumbs, cols = self.thumbs, min(self.cols, len(self.thumbs))
        rows = math.ceil(len(thumbs) / cols)
        cw = max(t.width for t in thumbs) + GAP
        ch = max(t.height for t in thumbs) + LABEL_HEIGHT + GAP
        sheet = Image.new("RGB", (cols * cw + GAP, rows * ch + GAP), (40, 40, 40))
        draw = ImageDraw.Draw(sheet)
        font = ImageFont.load_default()
        for k, (thumb, label, cov) in enumerate(zip(thumbs, self.labels, self.covs)):
            r, c = divmod(k, cols)
            x, y = GAP + c * cw, GAP + r * ch
            sheet.paste(thumb, (x, y))
            draw.text((x + 2, y + thumb.height + 3), f"{label}  cov {100 * cov:.1f}%", fill=(235, 235, 235),
                      font=font)
        path = Path(path)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        try:
            sheet.save(tmp, format="PNG", compress_level=PNG_LEVEL)
            os.replace(tmp, path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        return list(self.covs)


def write_contact_sheet(images: list[np.ndarray], labels: list[str], path: str | Path, *,
                        background=(0.0, 0.0, 0.0), thumb_longest: int = 320,
                        columns: int | None = None) -> list[float]:
    """Write the grid PNG of images already in memory (:class:`ContactSheet`); returns the coverage
    of every view."""
    if len(images) != len(labels) or not images:
        raise ValueError("need one label per image and at least one image")
    sheet = ContactSheet(len(images), background=background, thumb_longest=thumb_longest, columns=columns)
    for im, label in zip(images, labels):
        sheet.add(im, label)
    return sheet.write(path)
