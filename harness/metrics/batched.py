"""A view's pruned images scored together on the study's device: the torch forms of the built-in
metrics, batched, with the reference's side of each on the device once per view.

Torch forms (:data:`TORCH_METRICS`, :data:`TORCH_FAMILIES`): ``psnr`` (float64 squared errors of the
clamped images), ``ssim`` (:mod:`.ssim` with the ``conv2d`` Gaussian, :func:`.ssim.blur_torch`) and the
``mpeg`` / ``mpeg-qmiv`` families (:mod:`.mpeg_torch`); LPIPS is batched by the suite itself (its
reference features). A metric without a torch form (a plugin's) is computed by its own ``compute`` on
host copies of the batch, read back once and only when such a metric is asked for, so every
registered metric is measured on any device. The CPU forms stay the reference: ``tests`` compare
each torch form, run on CPU torch, with them (PSNR to 1e-12 dB, SSIM to 1e-12, the MPEG set bit for
bit or to 1e-12, :mod:`.mpeg_torch`).

Images arrive as one ``(N, H, W, 3)`` float32 tensor on the device, occupancy masks as ``(N, H, W)``
booleans (None: no OM metric asked for, or no alpha).
"""

from __future__ import annotations

import numpy as np
import torch

from harness.core.errors import InputError
from harness.metrics import registry as _registry
from harness.metrics.images import as_image, check_same_size
from harness.metrics.psnr import psnr_from_mse

#: metrics computed one by one that have a torch form here
TORCH_METRICS = ("psnr", "ssim")
#: families with a joint torch form: name -> the tool's QMIV mode
TORCH_FAMILIES = {"mpeg": False, "mpeg-qmiv": True}
#: device memory one image of a batch needs beyond its LPIPS pass, per pixel (the OM-SSIM's float64
#: accumulators and temporaries over three planes, IV-SSIM's integer pictures): an upper bound
BYTES_PER_PIXEL = 640
#: most images one batch holds
MAX_BATCH = 16


def batch_size(height: int, width: int, device) -> int:
    """Images per batch on ``device``: as many as fit in a quarter of its free memory, at most
    :data:`MAX_BATCH` (1 off CUDA: the CPU forms score one image at a time anyway)."""
    dev = torch.device(device)
    if dev.type != "cuda":
        return 1
    free, _ = torch.cuda.mem_get_info(dev)
    return int(max(1, min(MAX_BATCH, free // 4 // (height * width * BYTES_PER_PIXEL))))


def _split(names) -> tuple[dict[str, list[str]], list[str], list[str]]:
    """``names`` (LPIPS aside) as (torch family -> members, torch metrics, the rest)."""
    fams: dict[str, list[str]] = {}
    single, other = [], []
    for n in names:
        spec = _registry.METRICS.get(n)
        if n == "lpips":
            continue
        if spec.compute is None and spec.family in TORCH_FAMILIES:
            fams.setdefault(spec.family, []).append(n)
        elif n in TORCH_METRICS:
            single.append(n)
        else:
            other.append(n)
    return fams, single, other


class DeviceSide:
    """One reference image's side of the torch forms of ``names`` on ``device``: the image, its
    clamped float64 copy (PSNR), SSIM moments, the MPEG tool's 8-bit/YUV planes per mode, and the
    host image for the metrics without a torch form."""

    def __init__(self, image: np.ndarray, names, device):
        self.names = tuple(names)
        self.device = torch.device(device)
        self.fams, self.single, self.other = _split(self.names)
        self.image = torch.as_tensor(np.asarray(image, np.float32), device=self.device)
        self.host = np.asarray(image, np.float32) if self.other else None
        self.clamped = self.image.to(torch.float64).clamp(0, 1) if "psnr" in self.single else None
        self.ssim = None
        if "ssim" in self.single:
            from harness.metrics.ssim import SsimReference, blur_torch

            self.ssim = SsimReference(self.image[None], device=self.device, blur=blur_torch)
        from harness.metrics.mpeg_torch import ToolReferenceT

        self.tool = {fam: ToolReferenceT(self.image, qmiv=TORCH_FAMILIES[fam], device=self.device)
                     for fam in self.fams}


def batch_values(side: DeviceSide, images: torch.Tensor, masks: torch.Tensor | None) -> list[dict]:
    """The metrics of ``side`` (LPIPS aside) of each image of the batch against its reference, one
    dict per image (with ``occupancy`` % when an OM metric is asked for), as the CPU forms give them."""
    from harness.core.errors import InputError
    from harness.metrics.mpeg_members import size_problem, tool_members, tool_request
    from harness.metrics.mpeg_torch import tool_metrics_batch

    n = len(images)
    for fam, members in side.fams.items():
        why = size_problem(*images.shape[1:3], members, TORCH_FAMILIES[fam])
        if why:
            raise InputError("images", why)
    rows: list[dict] = [{} for _ in range(n)]
    with torch.inference_mode():
        if side.clamped is not None:
            d = side.clamped - images.to(torch.float64).clamp(0, 1)
            for row, m in zip(rows, (d * d).mean((1, 2, 3)).cpu().tolist()):
                row["psnr"] = psnr_from_mse(m)
        if side.ssim is not None:
            from harness.metrics.ssim import ssim_batch

            for row, v in zip(rows, ssim_batch(side.ssim, images, border="zero")):
                row["ssim"] = float(v)
    for fam, members in side.fams.items():
        base, flags = tool_request(members, TORCH_FAMILIES[fam])
        for row, r in zip(rows, tool_metrics_batch(side.tool[fam], images, masks, **flags)):
            row.update(tool_members(r, base, flags["om"]))
    if side.other:  # metrics without a torch form: their CPU form on the host copies
        from harness.metrics.pairs import pair_values

        host = images.cpu().numpy()
        host_masks = None if masks is None else masks.cpu().numpy()
        for k, row in enumerate(rows):
            row.update(pair_values(side.host, host[k], side.other, device="cpu",
                                   mask=None if host_masks is None else host_masks[k]))
    return rows


def masked_psnr(reference: torch.Tensor, images: torch.Tensor, mask: torch.Tensor) -> list[float]:
    """PSNR of each image against ``reference`` over the pixels of ``mask`` ``(H, W)`` (float64, as
    the CPU form :meth:`.suite.MetricSuite._photo_values`); 0.0 for an empty mask."""
    if not bool(mask.any()):
        return [0.0] * len(images)
    with torch.inference_mode():
        d = reference.to(torch.float64).clamp(0, 1)[mask] - images.to(torch.float64).clamp(0, 1)[:, mask]
        return [psnr_from_mse(m) for m in (d * d).mean((1, 2)).cpu().tolist()]


def to_batch(images, size, key: str, device) -> torch.Tensor:
    """``images`` (a list of ``(H, W, 3)`` arrays, or a ``(N, H, W, 3)`` tensor) as one float32 tensor
    on ``device``, checked as :func:`.images.as_image` checks an image (size ``size`` = the reference's)."""
    if isinstance(images, torch.Tensor):
        x = images.to(device=device, dtype=torch.float32)
        if x.dim() != 4 or x.shape[3] != 3 or tuple(x.shape[1:3]) != tuple(size):
            raise InputError(f"images of {key}", f"batch of shape {tuple(x.shape)} is not (N, {size[0]}, {size[1]}, 3)")
        if not bool(torch.isfinite(x).all()):
            raise InputError(f"images of {key}", "NaN or infinite pixel values")
        return x
    imgs = [as_image(im, f"image {i} of {key}") for i, im in enumerate(images)]
    ref = np.empty(tuple(size) + (3,), np.float32)
    for i, img in enumerate(imgs):
        check_same_size(ref, img, f"reference of {key}", f"image {i} of {key}")
    return torch.from_numpy(np.stack(imgs) if imgs else np.empty((0, *size, 3), np.float32)).to(device)


class ViewOnDevice:
    """A view's side of the torch forms, built once per reference: the reference's
    :class:`DeviceSide`, its occupancy (OM metrics), and, for a view with a photo, the photo's side and
    the photo metrics' mask (the unpruned render's alpha ≥ 0.5). :meth:`score` gives what
    :meth:`.suite.MetricSuite.score_many` gives, LPIPS aside."""

    def __init__(self, ref: np.ndarray, names, device, ref_alpha=None, photo=None, photo_mask=None):
        from harness.metrics.mpeg import OCCUPANCY_ALPHA

        self.base = [n for n in names if n != "lpips"]
        self.with_psnr = "psnr" in names
        self.device = torch.device(device)
        self.ref = DeviceSide(ref, self.base, device)
        self.wants_alpha = _registry.needs_alpha(names)
        self.occupancy = float(OCCUPANCY_ALPHA)
        self.ref_occupied = None if ref_alpha is None or not self.wants_alpha else \
            torch.as_tensor(np.asarray(ref_alpha, np.float32), device=self.device) >= self.occupancy
        self.photo = None if photo is None else DeviceSide(photo, self.base, device)
        self.photo_mask = None if photo_mask is None else torch.as_tensor(np.asarray(photo_mask), device=self.device)

    def _masks(self, alphas, n: int) -> torch.Tensor | None:
        """The OM mask of each image: occupied in either render (:func:`.mpeg.occupancy_mask`)."""
        if not self.wants_alpha or (self.ref_occupied is None and alphas is None):
            return None
        h, w = self.ref.image.shape[:2]
        masks = torch.zeros((n, h, w), dtype=torch.bool, device=self.device)
        if self.ref_occupied is not None:
            masks |= self.ref_occupied
        if alphas is not None:
            a = alphas if isinstance(alphas, torch.Tensor) else torch.from_numpy(np.stack(
                [np.asarray(x, np.float32) for x in alphas]))
            masks |= a.to(self.device, torch.float32).reshape(n, h, w) >= self.occupancy
        return masks

    def score(self, images: torch.Tensor, alphas=None) -> list[dict]:
        n = len(images)
        rows = batch_values(self.ref, images, self._masks(alphas, n))
        if self.photo is None:
            return rows
        pm = None if self.photo_mask is None else self.photo_mask[None].expand(n, *self.photo_mask.shape)
        gt = batch_values(self.photo, images, pm)
        full = torch.ones(images.shape[1:3], dtype=torch.bool, device=self.device)
        om = masked_psnr(self.photo.image, images, full if self.photo_mask is None else self.photo_mask) \
            if self.with_psnr else None
        share = 100.0 * float(self.photo_mask.to(torch.float64).mean()) if self.photo_mask is not None else 100.0
        for k, (row, g) in enumerate(zip(rows, gt)):
            row.update({_registry.GT_PREFIX + m: v for m, v in g.items() if m in self.base})
            if om is not None:
                row["gt_psnr_om"] = om[k]
            row["gt_occupancy"] = share
        return rows
