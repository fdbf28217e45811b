"""LPIPS v0.1 with the VGG16 trunk, with reference features computed once and reused.

LPIPS(x0, x1) = sum_l mean_{h,w} sum_c w_lc (f0_lchw - f1_lchw)^2, where f_l are the relu1_2, relu2_2,
relu3_3, relu4_3, relu5_3 activations of VGG16 on ``(2x - 1 - shift) / scale``, each unit-normalised
over channels (``f / (||f||_2 + 1e-10)``), and w_l the package's v0.1 linear weights. This is exactly
``lpips.LPIPS(net='vgg', version='0.1')`` (the 1x1 "lin" conv commutes with the spatial mean); the
trunk weights come from :mod:`harness.metrics.lpips_weights`, never from a download, and are assigned
to the uninitialised trunk of :mod:`harness.metrics.vgg16` (no random initialisation; neither
torchvision nor lpips is imported: the tests compare with the lpips package's own module).

Inputs are images ``(H, W, 3)`` in [0, 1] (clamped first, like PSNR), at least 16 px on each side
(relu5_3 is at 1/16 resolution). A pruned image against a cached reference costs one trunk pass, not
two: :meth:`LpipsVGG.features` once per view, then :meth:`LpipsVGG.distance` per pruned image.

Speed settings: ``torch.inference_mode``, channels-last tensors (oneDNN's preferred layout on CPU),
all of the process's cores, CUDA when present. ``precision="bfloat16"`` runs the trunk under
autocast (AMX/tensor cores) for speed at a small accuracy cost; the default and the reference
metric are float32.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from harness.core.errors import InputError
from harness.metrics.images import as_image
from harness.metrics.lpips_weights import N_LIN, load_backbone
from harness.metrics.vgg16 import scale_input, vgg16_trunk

MIN_SIDE = 16
EPS = 1e-10


@dataclass
class LpipsFeatures:
    """Unit-normalised trunk activations of one image: five ``(1, C_l, h_l, w_l)`` float32 tensors.

    Picklable; :func:`save_features` / :func:`load_features` store it as a torch file.
    ``size`` is the image's ``(H, W)`` so a mismatched pruned image is caught.
    """

    layers: tuple
    size: tuple

    def to(self, device) -> LpipsFeatures:
        return LpipsFeatures(tuple(t.to(device) for t in self.layers), self.size)

    @property
    def nbytes(self) -> int:
        return sum(t.numel() * t.element_size() for t in self.layers)


def save_features(feats: LpipsFeatures, path: str | Path) -> Path:
    """Write ``feats`` to ``path`` atomically (temp file + rename)."""
    path = Path(path)
    part = path.with_name(path.name + f".part{os.getpid()}")
    torch.save({"size": list(feats.size), "layers": [t.detach().cpu() for t in feats.layers]}, part)
    part.replace(path)
    return path


def load_features(path: str | Path, device="cpu") -> LpipsFeatures:
    """Read features written by :func:`save_features` (tensors only, no pickled code)."""
    payload = torch.load(Path(path), map_location=device, weights_only=True)
    return LpipsFeatures(tuple(payload["layers"]), tuple(payload["size"]))


def default_device() -> torch.device:
    return torch.device("cuda" if torch.cuda.is_available() else "cpu")


def use_all_cores() -> int:
    """Let torch use every core this process may run on; returns the thread count."""
    n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if torch.get_num_threads() < n:
        torch.set_num_threads(n)
    return torch.get_num_threads()


class LpipsVGG:
    """LPIPS-VGG v0.1 scorer with reusable reference features.

    ``weights``: path of the converted trunk (default: the fetched one; missing -> InputError
    telling to run ``harness fetch --weights``). ``batch_size``: images per trunk pass in
    :meth:`distances` (default 1 on CPU, which bounds memory to one image's activations, about
    1 GB at 1024x768; on CUDA as many as fit in a quarter of free memory, at most 16). Construction raises torch's
    thread count to every core the process may use (:func:`use_all_cores`).
    """

    def __init__(self, device=None, *, weights: str | Path | None = None, precision: str = "float32",
                 channels_last: bool = True, batch_size: int | None = None):
        if precision not in ("float32", "bfloat16"):
            raise ValueError(f"precision must be float32 or bfloat16, not {precision!r}")
        payload = load_backbone(weights)
        self.device = torch.device(device) if device is not None else default_device()
        self.threads = use_all_cores()
        self.precision = precision
        self.channels_last = channels_last
        self.batch_size = batch_size
        memory_format = torch.channels_last if channels_last else torch.contiguous_format
        # the converted trunk assigned to an uninitialised VGG16 (harness.metrics.vgg16); the v0.1 linear
        # layers are the package's own (equal to its vgg.pth, checked when the weights were converted)
        self._trunk = vgg16_trunk(payload["net"]).to(self.device, memory_format=memory_format)
        self._lin = [payload["lin"][f"lin{k}.model.1.weight"].reshape(-1).to(self.device)  # (C_l,) each
                     for k in range(N_LIN)]

    # -- passes -------------------------------------------------------------------------------
    def _to_input(self, images) -> torch.Tensor:
        """``images``: a list of ``(H, W, 3)`` arrays or a ``(N, H, W, 3)`` tensor (any device)."""
        x = images if isinstance(images, torch.Tensor) else torch.from_numpy(np.stack(images))
        x = x.to(self.device, torch.float32).permute(0, 3, 1, 2)
        x = scale_input(x.clamp(0.0, 1.0) * 2.0 - 1.0)
        return x.contiguous(memory_format=torch.channels_last if self.channels_last else torch.contiguous_format)

    def _normalised_layers(self, images) -> list[torch.Tensor]:
        x = self._to_input(images)
        if self.precision == "bfloat16":
            with torch.autocast(device_type=self.device.type, dtype=torch.bfloat16):
                outs = self._trunk(x)
        else:
            outs = self._trunk(x)
        layers = []
        for f in outs:
            f = f.float()
            layers.append(f / (torch.sqrt((f * f).sum(dim=1, keepdim=True)) + EPS))
        return layers

    def _check(self, image, source) -> np.ndarray:
        img = as_image(image, source)
        if min(img.shape[:2]) < MIN_SIDE:
            raise InputError(source, f"image {img.shape[1]}x{img.shape[0]} is too small for LPIPS-VGG "
                                     f"(needs at least {MIN_SIDE} px per side)")
        return img

    # -- public API ---------------------------------------------------------------------------
    def features(self, image, source: str = "reference image") -> LpipsFeatures:
        """Normalised trunk activations of ``image`` (compute once per reference view)."""
        img = self._check(image, source)
        with torch.inference_mode():
            layers = self._normalised_layers([img])
        return LpipsFeatures(tuple(layers), tuple(img.shape[:2]))  # same memory layout as later passes

    def distances(self, ref: LpipsFeatures, images, source: str = "image") -> np.ndarray:
        """LPIPS between the reference behind ``ref`` and each image of ``images``: float64 ``(n,)``."""
        return self.distances_to([ref], images, source)[:, 0]

    def distances_to(self, refs, images, source: str = "image") -> np.ndarray:
        """LPIPS of each image against each of several references (e.g. the unpruned render and the
        photo of a view): float64 ``(n_images, n_refs)``, one trunk pass per image."""
        imgs = [self._check(im, f"{source} {i}") for i, im in enumerate(images)]
        for ref in refs:
            for i, img in enumerate(imgs):
                if tuple(img.shape[:2]) != tuple(ref.size):
                    raise InputError(f"{source} {i}", f"size {img.shape[1]}x{img.shape[0]} differs from the "
                                                      f"reference's {ref.size[1]}x{ref.size[0]}")
        return self._distances(refs, imgs, len(imgs), imgs[0].shape[:2] if imgs else (1, 1))

    def distances_batch(self, refs, images: torch.Tensor) -> np.ndarray:
        """:meth:`distances_to` of a batch ``(N, H, W, 3)`` tensor already checked by the caller (on
        the study's device: no host copy); float64 ``(N, n_refs)``."""
        size = tuple(images.shape[1:3])
        if min(size) < MIN_SIDE:
            raise InputError("image", f"image {size[1]}x{size[0]} is too small for LPIPS-VGG "
                                      f"(needs at least {MIN_SIDE} px per side)")
        for ref in refs:
            if size != tuple(ref.size):
                raise InputError("image", f"size {size[1]}x{size[0]} differs from the reference's "
                                          f"{ref.size[1]}x{ref.size[0]}")
        return self._distances(refs, images, len(images), size)

    def _distances(self, refs, images, n: int, size) -> np.ndarray:
        refs = [ref.to(self.device) for ref in refs]
        step = self.batch_size or self._auto_batch(size)
        parts = []
        with torch.inference_mode():
            for start in range(0, n, step):
                layers = self._normalised_layers(images[start:start + step])
                parts.append(torch.stack([self._combine(layers, ref.layers) for ref in refs], 1).double())
        return torch.cat(parts).cpu().numpy() if parts else np.empty((0, len(refs)))

    def feature_distance(self, a: LpipsFeatures, b: LpipsFeatures) -> float:
        """LPIPS of two images from their stored features (no trunk pass)."""
        if tuple(a.size) != tuple(b.size):
            raise InputError("features", f"sizes differ: {a.size} vs {b.size}")
        with torch.inference_mode():
            return float(self._combine(a.to(self.device).layers, b.to(self.device).layers)[0])

    def _combine(self, layers, ref_layers) -> torch.Tensor:
        """Σ_l mean_hw Σ_c w_lc (f − f_ref)² per image of the batch ``layers``."""
        total = 0.0
        for f1, f0, w in zip(layers, ref_layers, self._lin):
            d = (f1 - f0).square_()
            total = total + torch.einsum("bchw,c->b", d, w) / (d.shape[2] * d.shape[3])
        return total

    def distance(self, ref: LpipsFeatures, image, source: str = "image") -> float:
        """LPIPS between the reference behind ``ref`` and ``image`` (one trunk pass)."""
        return float(self.distances(ref, [image], source)[0])

    def __call__(self, a, b) -> float:
        """LPIPS of a pair (two trunk passes, in step: :meth:`_pair`); symmetric."""
        a, b = self._check(a, "first image"), self._check(b, "second image")
        if a.shape[:2] != b.shape[:2]:
            raise InputError("second image", f"size {b.shape[1]}x{b.shape[0]} differs from the reference's "
                                             f"{a.shape[1]}x{a.shape[0]}")
        if self.precision != "float32":  # under autocast: the plain path
            return self.distance(self.features(a, "first image"), b, "second image")
        with torch.inference_mode():
            return float(self._pair(self._to_input([a]), self._to_input([b])))

    def _pair(self, xa: torch.Tensor, xb: torch.Tensor) -> torch.Tensor:
        """:meth:`_combine` of the two images' normalised layers, computed slice by slice: both
        images go through a slice of the trunk, the next slice's max-pool is taken, and only then
        are the two activations normalised and differenced in place and summed, and freed — one
        relu1_2-sized pair alive at a time instead of every layer of both images (1.9 GB for two
        1024x768 images before). The arithmetic is :meth:`distance`'s, operation for operation."""
        slices = [getattr(self._trunk, f"slice{k}") for k in range(1, len(self._lin) + 1)]
        ra, rb = slices[0](xa), slices[0](xb)
        total = 0.0
        for k, w in enumerate(self._lin):
            nxt = slices[k + 1] if k + 1 < len(slices) else None
            pa = pb = None
            if nxt is not None:  # the next slice's max-pool reads the raw activations: take it first
                pa, pb = nxt[0](ra), nxt[0](rb)
            fa = ra.div_(torch.sqrt((ra * ra).sum(dim=1, keepdim=True)) + EPS)
            fb = rb.div_(torch.sqrt((rb * rb).sum(dim=1, keepdim=True)) + EPS)
            d = fb.sub_(fa).square_()
            total = total + torch.einsum("bchw,c->b", d, w) / (d.shape[2] * d.shape[3])
            fa = fb = d = ra = rb = None  # freed before the next slice allocates its activations
            if nxt is not None:
                ra = nxt[1:](pa)
                pa = None
                rb = nxt[1:](pb)
                pb = None
        return total[0]

    def _auto_batch(self, size) -> int:
        if self.device.type != "cuda":
            return 1
        free, _ = torch.cuda.mem_get_info(self.device)
        per_image = size[0] * size[1] * 64 * 4 * 6  # ~six relu1-sized float32 buffers live at once
        return int(max(1, min(16, free // 4 // per_image)))
