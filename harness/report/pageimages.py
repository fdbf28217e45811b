"""The report page's image comparisons, from the renders a run stored under ``<run>/images/``.

Per scene (its first frame) the run keeps the unpruned render of the first held-out view
(``input.png``) and, for every method × variant × ratio it measured, the pruned render of the same
view (:func:`harness.report.record.image_name`). For each pair this module makes

* the two images for the slider, as JPEG (quality :data:`JPEG_QUALITY`, no chroma subsampling) —
  a viewing copy that keeps the page small;
* the amplified difference ``min(255, AMPLIFY · max over R, G, B of |pruned − reference|)`` as a
  grey image, computed from the lossless PNGs and stored as PNG, so it is faithful: black = identical,
  a difference of ``255 / AMPLIFY`` ≈ 32 levels or more in any channel is white (one grey channel
  rather than three: a third of the bytes, and the page embeds one per pruned render);
* the PSNR of this 8-bit pair (dB, +inf when identical) and the largest channel difference.

Everything is returned as ``data:`` URIs: the page needs no file beside it and no network. The
images are read through :func:`harness.io.safe.open_image` (a FIFO, a truncated PNG or a header of
20000×20000 pixels is one line naming the file, not a hang or a traceback).
"""

from __future__ import annotations

import base64
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.report import catalog
from harness.report.record import slug

AMPLIFY = 8
JPEG_QUALITY = 90


@dataclass
class Comparison:
    method: str
    variant: str
    ratio: float
    pruned: str        # data URI (JPEG)
    diff: str          # data URI (PNG), amplified |difference|
    psnr: float        # of this 8-bit pair
    max_diff: int      # largest channel difference, 0..255


@dataclass
class SceneImages:
    scene: str
    label: str
    reference: str     # data URI (JPEG)
    width: int
    height: int
    comparisons: list[Comparison]


def data_uri(img, fmt: str) -> str:
    buf = io.BytesIO()
    if fmt == "JPEG":
        img.convert("RGB").save(buf, "JPEG", quality=JPEG_QUALITY, subsampling=0, optimize=True)
        mime = "image/jpeg"
    else:
        img.save(buf, "PNG", optimize=True)
        mime = "image/png"
    return f"data:{mime};base64,{base64.b64encode(buf.getvalue()).decode('ascii')}"


def file_uri(path: Path) -> str:
    """A PNG file as a data URI, unchanged (read through the bounded reader)."""
    from harness.io.safe import read_bytes

    return "data:image/png;base64," + base64.b64encode(read_bytes(path, "image", "image")).decode("ascii")


def difference(ref: np.ndarray, pruned: np.ndarray) -> tuple[np.ndarray, float, int]:
    """(amplified max-channel |difference|, uint8 H×W; PSNR in dB of the 8-bit pair; largest
    channel difference)."""
    d = np.abs(ref.astype(np.int16) - pruned.astype(np.int16))
    mse = float(np.mean((d.astype(np.float64) / 255.0) ** 2))
    psnr = np.inf if mse == 0 else 10.0 * np.log10(1.0 / mse)
    return np.minimum(255, d.max(axis=2) * AMPLIFY).astype(np.uint8), psnr, int(d.max())


def _parse(name: str) -> tuple[str, str, float] | None:
    """(method, variant, ratio) of ``<method>__<variant>__r<ratio>.png``."""
    parts = name[:-4].split("__")
    if len(parts) != 3 or not parts[2].startswith("r"):
        return None
    try:
        return parts[0], parts[1], float(parts[2][1:])
    except ValueError:
        return None


def _first_frame_dir(images: Path, scene: str) -> Path | None:
    d = images / slug(scene)
    if (d / "input.png").exists():
        return d
    subs = sorted(p for p in d.glob("*") if p.is_dir() and (p / "input.png").exists()) if d.exists() else []
    return subs[0] if subs else None


def scene_images(images: Path, scenes: list[tuple[str, str]], known: dict) -> list[SceneImages]:
    """Comparisons per scene; ``scenes`` = [(scene, label)], ``known`` maps the file name of a method
    or variant to its name (a render's file name carries them as file names)."""
    from PIL import Image

    from harness.io.safe import open_image  # regular files, size-capped, pixel count checked first

    out = []
    for scene, label in scenes:
        d = _first_frame_dir(images, scene)
        if d is None:
            continue
        ref_img = open_image(d / "input.png", "run image")
        ref = np.asarray(ref_img)
        found = []
        for f in sorted(d.glob("*__*__r*.png")):
            key = _parse(f.name)
            if key is None:
                continue
            img = open_image(f, "run image")
            if img.size != ref_img.size:
                continue
            amp, psnr, mx = difference(ref, np.asarray(img))
            method, variant = known.get(key[0], key[0]), known.get(key[1], key[1])
            found.append(Comparison(method, variant, key[2], data_uri(img, "JPEG"),
                                    data_uri(Image.fromarray(amp), "PNG"), psnr, mx))
        order = {m: i for i, m in enumerate(catalog.method_order([c.method for c in found]))}
        found.sort(key=lambda c: (order[c.method], c.variant != "default", c.variant, c.ratio))
        out.append(SceneImages(scene, label, data_uri(ref_img, "JPEG"), ref_img.width, ref_img.height, found))
    return out
