"""The two array libraries the projection runs on: numpy on the CPU, torch for gradients or a GPU.

:mod:`renderers.projection` and :mod:`renderers.sh` are written once against the operations below;
:func:`ops_for` picks the namespace from the arrays it is given. The GL renderer projects with
numpy on the CPU (no torch import: ``harness render`` starts in a fraction of the time and memory)
and with torch on a CUDA device; the reference renderer and the camera-aware pruners use torch
(autograd). Most operations share their name in both libraries (``stack``, ``exp``, ``sqrt``,
``where``, ``clip`` ...) and are used directly; the few that differ are wrapped here.

Each operation the projection uses is elementwise or a fixed-order sum (see
:mod:`renderers.projection`), so in either library a splat's values depend on that splat alone. The
two libraries agree to float32 rounding: their ``exp`` and ``log`` kernels may differ in the last
bit (``tests/test_projection_arrays.py`` bounds it).
"""

from __future__ import annotations

import contextlib

import numpy as np


class NumpyOps:
    """numpy under the names the projection uses."""

    lib = np
    float32 = np.float32
    float64 = np.float64

    @staticmethod
    def asarray(a, dtype, like=None):
        return np.ascontiguousarray(a, dtype=dtype)

    @staticmethod
    def flatnonzero(mask):
        return np.flatnonzero(mask)

    @staticmethod
    def as_index(x):
        return x.astype(np.int64)

    @staticmethod
    def detach(x):
        return x

    @staticmethod
    def no_grad():
        return contextlib.nullcontext()

    @staticmethod
    def argsort_stable(x):
        return np.argsort(x, kind="stable")

    @staticmethod
    def to_numpy(x) -> np.ndarray:
        return np.asarray(x)

    @staticmethod
    def to_host(*xs) -> list[np.ndarray]:
        return [np.asarray(x) for x in xs]

    @staticmethod
    def cast(x, dtype):
        return x.astype(dtype, copy=False)


class TorchOps:
    """torch under the same names (imported when first used)."""

    def __init__(self):
        import torch

        self.lib = torch
        self.float32, self.float64 = torch.float32, torch.float64

    def asarray(self, a, dtype, like=None):
        return self.lib.as_tensor(a, dtype=dtype, device=None if like is None else like.device)

    def flatnonzero(self, mask):
        return self.lib.nonzero(mask).reshape(-1)

    @staticmethod
    def as_index(x):
        return x.long()

    @staticmethod
    def detach(x):
        return x.detach()

    def no_grad(self):
        return self.lib.no_grad()

    def argsort_stable(self, x):
        return self.lib.sort(x, stable=True).indices

    @staticmethod
    def to_numpy(x) -> np.ndarray:
        return x.detach().cpu().numpy()

    def to_host(self, *xs) -> list[np.ndarray]:
        """numpy copies of ``xs``; from a CUDA device each is copied into page-locked host memory
        without waiting, and the device is waited for once, after the last copy."""
        if not any(x.device.type == "cuda" for x in xs):
            return [self.to_numpy(x) for x in xs]
        host = []
        for x in xs:
            buf = self.lib.empty(x.shape, dtype=x.dtype, pin_memory=x.device.type == "cuda")
            host.append(buf.copy_(x.detach(), non_blocking=True))
        for dev in {x.device for x in xs if x.device.type == "cuda"}:
            self.lib.cuda.synchronize(dev)
        return [h.numpy() for h in host]

    @staticmethod
    def cast(x, dtype):
        return x.to(dtype)


NUMPY = NumpyOps()
_torch_ops: TorchOps | None = None


def torch_ops() -> TorchOps:
    global _torch_ops
    if _torch_ops is None:
        _torch_ops = TorchOps()
    return _torch_ops


def ops_for(x):
    """The namespace of array ``x``: :data:`NUMPY` for a numpy array, else torch's."""
    return NUMPY if isinstance(x, np.ndarray) else torch_ops()
