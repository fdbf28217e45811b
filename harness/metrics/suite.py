"""Image metrics used by the field: PSNR, SSIM (3DGS convention), LPIPS v0.1 VGG.

* :func:`compare_images` scores one pair.
* :class:`MetricSuite` scores many images of the same view against that view's reference, computing
  the reference's LPIPS features once (kept in memory, least recently used views evicted, and
  optionally on disk so an evicted view is reloaded instead of recomputed).

Every function takes float images ``(H, W, 3)`` nominally in [0, 1] and clamps them to [0, 1].
Conventions are documented in :mod:`.psnr`, :mod:`.ssim`, :mod:`.lpips_vgg`.
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


def _pair_metrics(ref: np.ndarray, img: np.ndarray, yuv: bool, ssim_border: str, device,
                  names=METRICS) -> dict:
    out = {}
    if "psnr" in names:
        out["psnr"] = psnr_from_mse(mse(ref, img))
    if "ssim" in names:
        out["ssim"] = float(ssim_batch(ref[None], img[None], border=ssim_border, device=device)[0])
    if yuv:
        out.update(yuv_psnr(ref, img))
    return out


def compare_images(a, b, *, lpips_model: LpipsVGG | None = None, yuv: bool = False) -> dict:
    """``{"psnr", "ssim", "lpips"}`` (plus ``psnr_y/u/v/yuv`` with ``yuv=True``) of two images."""
    a, b = as_image(a, "first image"), as_image(b, "second image")
    check_same_size(a, b)
    model = lpips_model or default_lpips()
    out = _pair_metrics(a, b, yuv, "zero", model.device)
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

    def _stem(self, key: str) -> Path:
        return self.feature_dir / hashlib.sha256(str(key).encode()).hexdigest()[:24]

    def _remember(self, key: str, image: np.ndarray, feats: LpipsFeatures) -> None:
        self._cache[key] = (image, feats)
        self._cache.move_to_end(key)
        while len(self._cache) > self.max_in_memory:
            self._cache.popitem(last=False)

    def reference(self, view_key: str, image) -> None:
        """Register (or replace) the reference image of ``view_key`` and cache its features."""
        key = str(view_key)
        img = as_image(image, f"reference of {key}")
        feats = self.lpips.features(img, f"reference of {key}") if self.lpips is not None else None
        if self.feature_dir is not None and feats is not None:
            stem = self._stem(key)
            part = stem.with_name(stem.name + f".part{os.getpid()}.npy")
            np.save(part, img)
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
                return img, feats
        raise KeyError(f"no reference registered for view {key!r}; call reference() first")

    def score_many(self, view_key: str, images) -> list[dict]:
        """Metrics of each image against the reference of ``view_key`` (LPIPS batched)."""
        key = str(view_key)
        ref, feats = self._get(key)
        imgs = [as_image(im, f"image {i} of {key}") for i, im in enumerate(images)]
        for i, img in enumerate(imgs):
            check_same_size(ref, img, f"reference of {key}", f"image {i} of {key}")
        lp = self.lpips.distances(feats, imgs, f"image of {key}") if self.lpips is not None else [None] * len(imgs)
        rows = []
        for img, d in zip(imgs, lp):
            row = _pair_metrics(ref, img, self.yuv, self.ssim_border, self.device, self.names)
            if d is not None:
                row["lpips"] = float(d)
            rows.append(row)
        return rows

    def score(self, view_key: str, image) -> dict:
        """``{"psnr", "ssim", "lpips"}`` of ``image`` against the reference of ``view_key``."""
        return self.score_many(view_key, [image])[0]
