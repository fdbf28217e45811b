"""Image metrics used by the field: PSNR, SSIM (3DGS convention), LPIPS v0.1 VGG, and MPEG's
mpeg-gsc-metrics set (:mod:`.mpeg`: RGB-/YUV-PSNR, YUV-SSIM and their occupancy-masked variants).

* :func:`compare_images` scores one pair.
* :class:`MetricSuite` scores many images of the same view against that view's reference, computing
  the reference's LPIPS features once (kept in memory, least recently used views evicted, and
  optionally on disk so an evicted view is reloaded instead of recomputed), and its side of SSIM and
  of the MPEG set (8-bit/YUV planes, SSIM window moments) once (:func:`reference_sides`).

Every function takes float images ``(H, W, 3)`` nominally in [0, 1] and clamps them to [0, 1]
(the MPEG metrics quantise them to 8 bit as the tool does). Conventions are documented in
:mod:`.psnr`, :mod:`.ssim`, :mod:`.lpips_vgg`, :mod:`.mpeg`. The OM metrics need occupancy: pass each
render's alpha (``reference(..., alpha=)``, ``score(..., alpha=)``); the mask is the union of both
renders' occupancy (:func:`.mpeg.occupancy_mask`); without alphas it is all ones (the tool's
maskless overload: OM = full frame).
"""

from __future__ import annotations

import hashlib
import os
from collections import OrderedDict
from functools import lru_cache
from pathlib import Path

import numpy as np

from harness.metrics import registry as _registry
from harness.metrics.images import as_image, check_same_size, read_image
from harness.metrics.lpips_vgg import (
    LpipsFeatures,
    LpipsVGG,
    load_features,
    save_features,
)
from harness.metrics.psnr import mse, psnr, psnr_from_mse, summarize_psnr, yuv_psnr
from harness.metrics.ssim import ssim, ssim_batch

__all__ = [
    "METRICS",
    "LpipsFeatures",
    "LpipsVGG",
    "MetricSuite",
    "compare_images",
    "default_lpips",
    "load_features",
    "psnr",
    "read_image",
    "save_features",
    "ssim",
    "summarize_psnr",
    "yuv_psnr",
]


@lru_cache(maxsize=1)
def default_lpips() -> LpipsVGG:
    """One shared :class:`LpipsVGG` (default device, float32) per process."""
    return LpipsVGG()


METRICS = tuple(m.name for m in _registry.METRICS)
MPEG_NAMES = set(_registry.mpeg_names(False) + _registry.mpeg_names(True))


def mpeg_values(ref, img, names, mask=None, prepared=None) -> dict:
    """The requested names of the mpeg / mpeg-qmiv families for one pair (8-bit, as the tool), plus
    ``occupancy`` (%) when an OM metric was asked for. ``prepared``: ``{qmiv: ToolReference}`` of
    ``ref`` (:func:`reference_sides`), when the reference is measured against many images."""
    from harness.metrics.mpeg import tool_metrics

    out = {}
    for qmiv, sfx in ((False, ""), (True, "_qmiv")):
        wanted = [n for n in _registry.mpeg_names(qmiv) if n in names]
        if not wanted:
            continue
        om = any("_om" in n for n in wanted)
        ssim_on = any("ssim" in n for n in wanted)
        r = tool_metrics((prepared or {}).get(qmiv, ref), img, mask, qmiv=qmiv, ssim=ssim_on, om=om)
        out.update({n: float(r[n[: -len(sfx)] if sfx else n]) for n in wanted})
        if om:
            out["occupancy"] = float(r["occupancy"])
    return out


def reference_sides(ref: np.ndarray, names, device) -> dict:
    """What the SSIM and MPEG metrics compute from a reference alone (:class:`.ssim.SsimReference`;
    :class:`.mpeg.ToolReference` per mode), once for every image it is compared with; the values
    are those of scoring each pair from scratch, bit for bit."""
    from harness.metrics.mpeg import ToolReference
    from harness.metrics.ssim import SsimReference

    sides: dict = {"mpeg": {}}
    if "ssim" in names:
        sides["ssim"] = SsimReference(ref[None], device=device)
    for qmiv in (False, True):
        if set(_registry.mpeg_names(qmiv)) & set(names):
            sides["mpeg"][qmiv] = ToolReference(ref, qmiv=qmiv)
    return sides


def _pair_metrics(ref: np.ndarray, img: np.ndarray, yuv: bool, ssim_border: str, device,
                  names=METRICS, mask=None, sides=None) -> dict:
    sides = sides or {}
    out = mpeg_values(ref, img, names, mask, sides.get("mpeg")) if MPEG_NAMES & set(names) else {}
    if "psnr" in names:
        out["psnr"] = psnr_from_mse(mse(ref, img))
    if "ssim" in names:
        first = sides.get("ssim", ref[None])
        out["ssim"] = float(ssim_batch(first, img[None], border=ssim_border, device=device)[0])
    if yuv:
        out.update(yuv_psnr(ref, img))
    return out


def compare_images(a, b, *, lpips_model: LpipsVGG | None = None, yuv: bool = False,
                   names=("psnr", "ssim", "lpips"), mask=None) -> dict:
    """``{"psnr", "ssim", "lpips"}`` (plus ``psnr_y/u/v/yuv`` with ``yuv=True``) of two images, or
    the metrics ``names`` (MPEG ones with ``occupancy`` when masked; ``mask``: see :mod:`.mpeg`).

    uint8 images are scored by the MPEG metrics as they are (no float round trip)."""
    raw_a, raw_b = a, b
    a, b = as_image(a, "first image"), as_image(b, "second image")
    check_same_size(a, b)
    out = {}
    if MPEG_NAMES & set(names):
        u8 = lambda raw, f: raw if isinstance(raw, np.ndarray) and raw.dtype == np.uint8 and raw.ndim == 3 \
            and raw.shape[2] >= 3 else f  # noqa: E731
        out.update(mpeg_values(u8(raw_a, a), u8(raw_b, b), names, mask))
    rest = [n for n in names if n not in MPEG_NAMES]
    model = None
    if "lpips" in rest:
        model = lpips_model or default_lpips()
    out.update(_pair_metrics(a, b, yuv, "zero", model.device if model else None, rest))
    if model is not None:
        out["lpips"] = model(a, b)
    return out


class MetricSuite:
    """Scores images against per-view references, with each reference's LPIPS features cached.

    ``suite.reference(key, image)`` registers a view's reference; ``suite.score(key, image)`` (or
    ``score_many``) then costs one LPIPS trunk pass per image. At most ``max_in_memory`` views keep
    their features in memory (about 380 MB per 1024x768 view); with ``feature_dir`` every reference is
    also written there (features + image, atomically) and reloaded when evicted. ``names`` selects
    the metrics (a subset of ``METRICS``); without "lpips" no network is loaded. A model the suite
    creates itself leaves the process's torch thread count as it found it (the runner budgets
    workers × threads ≤ cores).
    """

    def __init__(self, lpips_model: LpipsVGG | None = None, *, names=METRICS, device=None,
                 feature_dir: str | Path | None = None, max_in_memory: int = 4, yuv: bool = False,
                 ssim_border: str = "zero"):
        self.names = tuple(names)
        unknown = sorted(set(self.names) - set(METRICS))
        if unknown:
            raise ValueError(f"unknown metric(s) {', '.join(unknown)}; known: {', '.join(METRICS)}")
        if "lpips" in self.names and lpips_model is None:
            import torch

            threads = torch.get_num_threads()
            lpips_model = LpipsVGG(device=device) if device is not None else default_lpips()
            torch.set_num_threads(threads)
        self.lpips = lpips_model if "lpips" in self.names else None
        self.device = self.lpips.device if self.lpips is not None else device
        self.feature_dir = Path(feature_dir) if feature_dir is not None else None
        if self.feature_dir is not None:
            self.feature_dir.mkdir(parents=True, exist_ok=True)
        self.max_in_memory = max(1, int(max_in_memory))
        self.yuv = yuv
        self.ssim_border = ssim_border
        self._cache: OrderedDict[str, tuple[np.ndarray, LpipsFeatures]] = OrderedDict()
        self._alpha: dict[str, np.ndarray] = {}  # reference alphas (OM metrics), evicted with _cache
        self._sides: dict[str, dict] = {}  # reference_sides of the views in _cache, evicted with it
        self.wants_alpha = any("_om" in n for n in self.names if n in MPEG_NAMES)

    def _stem(self, key: str) -> Path:
        return self.feature_dir / hashlib.sha256(str(key).encode()).hexdigest()[:24]

    def _remember(self, key: str, image: np.ndarray, feats: LpipsFeatures) -> None:
        self._cache[key] = (image, feats)
        self._cache.move_to_end(key)
        while len(self._cache) > self.max_in_memory:
            gone, _ = self._cache.popitem(last=False)
            self._alpha.pop(gone, None)
            self._sides.pop(gone, None)

    def reference(self, view_key: str, image, alpha=None) -> None:
        """Register (or replace) the reference image of ``view_key`` and cache its features
        (``alpha``: the render's (H, W) alpha, for the OM metrics' occupancy)."""
        key = str(view_key)
        self._alpha.pop(key, None)
        self._sides.pop(key, None)
        if alpha is not None:
            self._alpha[key] = np.asarray(alpha, np.float32)
        img = as_image(image, f"reference of {key}")
        feats = self.lpips.features(img, f"reference of {key}") if self.lpips is not None else None
        if self.feature_dir is not None and feats is not None:
            stem = self._stem(key)
            part = stem.with_name(stem.name + f".part{os.getpid()}.npy")
            np.save(part, img)
            if alpha is not None:
                np.save(stem.with_suffix(".alpha.npy"), self._alpha[key])
            save_features(feats, stem.with_suffix(".lpips.pt"))
            part.replace(stem.with_suffix(".ref.npy"))
        self._remember(key, img, feats)

    def has_reference(self, view_key: str) -> bool:
        key = str(view_key)
        return key in self._cache or (self.feature_dir is not None and self._stem(key).with_suffix(".ref.npy").is_file())

    def _get(self, key: str) -> tuple[np.ndarray, LpipsFeatures]:
        if key in self._cache:
            self._cache.move_to_end(key)
            return self._cache[key]
        if self.feature_dir is not None:
            stem = self._stem(key)
            if stem.with_suffix(".ref.npy").is_file() and stem.with_suffix(".lpips.pt").is_file():
                img = np.load(stem.with_suffix(".ref.npy"), allow_pickle=False)
                feats = load_features(stem.with_suffix(".lpips.pt"), self.lpips.device)
                self._remember(key, img, feats)
                if stem.with_suffix(".alpha.npy").is_file():
                    self._alpha[key] = np.load(stem.with_suffix(".alpha.npy"), allow_pickle=False)
                return img, feats
        raise KeyError(f"no reference registered for view {key!r}; call reference() first")

    def score_many(self, view_key: str, images, alphas=None) -> list[dict]:
        """Metrics of each image against the reference of ``view_key`` (LPIPS batched); ``alphas``
        (one per image, or None) give the OM metrics' occupancy together with the reference's."""
        key = str(view_key)
        ref, feats = self._get(key)
        imgs = [as_image(im, f"image {i} of {key}") for i, im in enumerate(images)]
        for i, img in enumerate(imgs):
            check_same_size(ref, img, f"reference of {key}", f"image {i} of {key}")
        lp = self.lpips.distances(feats, imgs, f"image of {key}") if self.lpips is not None else [None] * len(imgs)
        rows = []
        ref_alpha = self._alpha.get(key)
        for i, (img, d) in enumerate(zip(imgs, lp)):
            alpha = None if alphas is None else alphas[i]
            mask = None
            if self.wants_alpha and (ref_alpha is not None or alpha is not None):
                from harness.metrics.mpeg import occupancy_mask

                mask = occupancy_mask(*(x for x in (ref_alpha, alpha) if x is not None))
            if key not in self._sides:  # also after a reload from feature_dir
                self._sides[key] = reference_sides(ref, self.names, self.device)
            row = _pair_metrics(ref, img, self.yuv, self.ssim_border, self.device, self.names, mask, self._sides[key])
            if d is not None:
                row["lpips"] = float(d)
            rows.append(row)
        return rows

    def score(self, view_key: str, image, alpha=None) -> dict:
        """``{"psnr", "ssim", "lpips"}`` (the suite's names) of ``image`` against the reference of ``view_key``."""
        return self.score_many(view_key, [image], None if alpha is None else [alpha])[0]
