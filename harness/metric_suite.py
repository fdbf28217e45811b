"""Per-view metric state for the runner: the reference image and its LPIPS features, kept once.

``suite.reference(key, ref)`` stores the clamped reference and (if LPIPS is requested) its VGG
features; ``suite.score(key, img)`` then costs one PSNR, one SSIM and one VGG pass for the pruned
image only. Only the latest reference is kept (a view task measures all of its pruned sets before
the next view), which bounds memory: LPIPS features of a 1024x768 view are ~400 MB.

Metric definitions are those of :mod:`harness.metrics` (PSNR +inf for identical images, SSIM with the
3DGS convention, LPIPS v0.1 VGG).
"""

from __future__ import annotations

import numpy as np


class MetricSuite:
    def __init__(self, names: tuple[str, ...], device: str = "cpu"):
        self.names = tuple(names)
        self.device = device
        self._lpips = None
        if "lpips" in self.names:
            import torch

            from harness.metrics.lpips_vgg import LpipsVGG

            threads = torch.get_num_threads()
            self._lpips = LpipsVGG(device=device)
            torch.set_num_threads(threads)  # keep the pool's workers x threads <= cores budget
        self._key = None
        self._ref = None
        self._feats = None

    def reference(self, key: str, image: np.ndarray) -> None:
        if key == self._key:
            return
        self._key, self._feats = None, None
        self._ref = np.clip(np.asarray(image, dtype=np.float32), 0.0, 1.0)
        if self._lpips is not None:
            self._feats = self._lpips.features(self._ref)
        self._key = key

    def score(self, key: str, image: np.ndarray) -> dict[str, float]:
        if key != self._key:
            raise KeyError(f"reference {key[:12]} was not set; call reference() first")
        from harness.metrics.psnr import psnr
        from harness.metrics.ssim import ssim

        img = np.clip(np.asarray(image, dtype=np.float32), 0.0, 1.0)
        out = {}
        if "psnr" in self.names:
            out["psnr"] = psnr(self._ref, img)
        if "ssim" in self.names:
            out["ssim"] = ssim(self._ref, img, device=self.device)
        if "lpips" in self.names:
            out["lpips"] = self._lpips.distance(self._feats, img)
        return out
