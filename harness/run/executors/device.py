"""How many local worker processes hold the study's device (a GPU), decided in the driver without
opening the device there.

On a GPU run (``protocol.device: cuda``) the local executor keeps two kinds of worker: the CPU
workers (``workers`` of them: loading, camera-free scoring, everything numpy/numba) and a few
*device workers* that alone run the tasks that compute on the device (renders and metric batches of
the views, scoring by pruners that declare ``uses_device``). Only the device workers initialise CUDA,
so ``workers`` processes never each create a CUDA context and compete for the device's memory.

How many device workers (``executor.device_workers``; 0 = decide here): one per
:data:`GIB_PER_WORKER` GiB of the device's free memory, at least 1, at most :data:`MOST_AUTO` and
``workers``. The device runs one kernel stream at a time; the extra feeders only overlap the CPU share
of a device task (a view's packing, mask reads, cache writes) with another's device work, so a few
suffice. The free memory is asked of ``nvidia-smi`` (NVML), not of torch: the driver never opens a
CUDA context. Without ``nvidia-smi`` (or on a device it does not know), one device worker.
"""

from __future__ import annotations

import os
import shutil
import subprocess

#: free device memory per automatic device worker: its CUDA context, a metric batch (a quarter of the
#: free memory at most, :func:`harness.metrics.batched.batch_size`), a camera-aware pruner's tensors
GIB_PER_WORKER = 12
#: the most device workers chosen automatically (``executor.device_workers`` may ask for more)
MOST_AUTO = 4


def is_device(device: str | None) -> bool:
    """Is ``device`` a torch device other than the CPU ("cuda", "cuda:1", "mps", ...)?"""
    return bool(device) and str(device).split(":", 1)[0].strip().lower() != "cpu"


def _nvml_index(device: str) -> str:
    """``nvidia-smi -i`` of the torch device ``cuda[:k]``: the k-th of ``CUDA_VISIBLE_DEVICES`` when
    that is set (an index or a UUID), else k."""
    k = int(device.split(":", 1)[1]) if ":" in device else 0
    visible = [v.strip() for v in os.environ.get("CUDA_VISIBLE_DEVICES", "").split(",") if v.strip()]
    return visible[k] if k < len(visible) else str(k)


def free_bytes(device: str, timeout: float = 10.0) -> int | None:
    """Free memory of a CUDA device by ``nvidia-smi`` (None: not a CUDA device, no ``nvidia-smi``, or
    no answer)."""
    if not str(device).startswith("cuda") or shutil.which("nvidia-smi") is None:
        return None
    try:
        out = subprocess.run(["nvidia-smi", "--query-gpu=memory.free", "--format=csv,noheader,nounits",
                              "-i", _nvml_index(str(device))], capture_output=True, text=True, timeout=timeout,
                             check=True).stdout
        return int(float(out.strip().splitlines()[0])) << 20  # MiB
    except (OSError, ValueError, IndexError, subprocess.SubprocessError):
        return None


def device_worker_count(device: str, workers: int, asked: int = 0, free: int | None = None) -> int:
    """Device workers of a local run (module docstring): 0 when ``device`` is the CPU or one worker
    computes in-process; ``asked`` when given (> 0); else by ``free`` bytes of device memory (default:
    :func:`free_bytes`)."""
    if not is_device(device) or workers <= 1:
        return 0
    if asked > 0:
        return int(asked)
    free = free_bytes(device) if free is None else free
    if free is None:
        return 1
    return max(1, min(MOST_AUTO, workers, free // (GIB_PER_WORKER << 30)))
