"""A batch of GL frames into a torch tensor on the study's device: one host buffer per batch,
page-locked ("pinned") when the device is CUDA, that every framebuffer of the batch is read into
(``glReadPixels`` straight into its slice), then one copy to the device for the whole batch
(``non_blocking`` from pinned memory: a DMA transfer the CPU does not stage). The compositing with
the background, ``C + T·bg``, and the alpha ``1 − T`` then run on the device, the same float32
operations in the same order as the host path of :meth:`renderers.gl.GLRenderer.draw`, so each
image is bit for bit its ``draw``.

**Why not CUDA–GL interop.** Sharing the renderbuffer with CUDA without a host copy needs the CUDA
runtime's graphics interop (``cudaGraphicsGLRegisterImage``, map, ``cudaMemcpy2DFromArray``), which
torch does not expose; ``cuda-python`` or ``pycuda`` do, and neither is a dependency (a GPU machine
without registries has only what a session carries). Reading back through pinned memory costs one
device → host → device round trip per batch, with no per-image host arrays, no host compositing and
no pageable staging copy; measured on the CPU side in ``results/bench/gpu-full.md``.
"""

from __future__ import annotations

import numpy as np
import torch


def on_cuda(device) -> bool:
    """Whether frames for ``device`` go through pinned memory: a CUDA device torch can use."""
    return device is not None and torch.device(device).type == "cuda" and torch.cuda.is_available()


def host_buffer(count: int, height: int, width: int, device) -> torch.Tensor:
    """An uninitialised ``(count, height, width, 4)`` float32 host tensor for the batch's RGBT
    frames, page-locked when ``device`` is CUDA (:func:`on_cuda`)."""
    return torch.empty((count, height, width, 4), dtype=torch.float32, pin_memory=on_cuda(device))


def to_device(rgbt: torch.Tensor, device, background, with_alpha: bool):
    """``(images (N, H, W, 3), alphas (N, H, W) or None)`` on ``device`` from the host RGBT frames
    (Σ cᵢαᵢTᵢ and T): one copy, then ``C + T·bg`` and ``1 − T`` there."""
    frames = rgbt.to(device, non_blocking=True)
    bg = torch.as_tensor(np.asarray(background, dtype=np.float32).reshape(3), device=frames.device)
    images = frames[..., :3] + frames[..., 3:4] * bg
    return images, (1.0 - frames[..., 3]) if with_alpha else None
