"""Where and on what a result was measured: commit, machine, CPU seconds, a speed calibration.

``time_calibration`` times a fixed workload so that stage times from different moments and machines
can be compared as ratios (``harness track`` divides by it; benchmarks record it).
"""

from __future__ import annotations

import os
import platform
import statistics
import subprocess
import time
from pathlib import Path

import numpy as np

from harness.core.paths import REPO_ROOT


def _git(*args) -> str:
    try:
        return subprocess.run(["git", *args], cwd=REPO_ROOT, capture_output=True, text=True, timeout=10,
                              check=False).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def git_commit() -> str:
    """HEAD, with ``+dirty`` when tracked files differ from it (the numbers are then not reproducible
    from the commit alone)."""
    head = _git("rev-parse", "HEAD")
    return f"{head}+dirty" if head and _git("status", "--porcelain", "--untracked-files=no") else head


#: x86 vector extensions, widest first (a record names the first this CPU has)
SIMD_LEVELS = ("avx512f", "avx2", "avx", "sse4_2")


def cpu_model() -> tuple[str, str]:
    """(model name, widest vector extension) of this machine's CPU. Results do not depend on threads,
    workers or load, but float rounding in the last bits may depend on the CPU: the GL renderer (Mesa
    llvmpipe) compiles its shaders for the CPU it runs on, so a record names it."""
    try:
        info = Path("/proc/cpuinfo").read_text(errors="replace")
    except OSError:
        return platform.processor() or platform.machine(), ""
    field = lambda key: next((ln.split(":", 1)[1].strip() for ln in info.splitlines()  # noqa: E731
                              if ln.startswith(key)), "")
    flags = set(field("flags").split())
    return field("model name") or platform.machine(), next((f for f in SIMD_LEVELS if f in flags), "")


def describe_machine() -> dict:
    """What the numbers were measured on."""
    import torch

    cpu, simd = cpu_model()
    return {"platform": platform.platform(), "python": platform.python_version(), "cpus": os.cpu_count(),
            "cpu": cpu, "simd": simd, "torch": torch.__version__, "torch_threads": torch.get_num_threads(),
            "cuda": torch.cuda.get_device_name(0) if torch.cuda.is_available() else None}


def cpu_seconds() -> float:
    """User + system CPU seconds of this process and its finished children (the pool's workers):
    the work done, independent of how many other processes shared the cores."""
    import resource

    total = 0.0
    for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN):
        r = resource.getrusage(who)
        total += r.ru_utime + r.ru_stime
    return total


def calibration_workload(seed: int = 0) -> None:
    """A fixed mix of the kernels the harness spends its time in: dense float32 matmul (LPIPS trunk
    stand-in), a 3×3 convolution stack in torch, float64 sorting and gathers (ranking, neighbour
    search), and elementwise exp/sqrt (rendering). Same work on every call; ~0.2 s on one modern core."""
    import torch

    rng = np.random.default_rng(seed)
    a = rng.standard_normal((384, 384)).astype(np.float32)
    for _ in range(4):
        a = np.tanh(a @ a.T * (1.0 / 384.0))
    x = rng.standard_normal(400_000)
    order = np.argsort(x, kind="stable")
    np.take(x, order).cumsum()
    np.sqrt(np.exp(-0.5 * x * x) + 1.0).sum()
    with torch.inference_mode():
        g = torch.Generator().manual_seed(seed)
        img = torch.randn(1, 16, 96, 96, generator=g)
        w = torch.randn(16, 16, 3, 3, generator=g) * 0.1
        for _ in range(6):
            img = torch.relu(torch.nn.functional.conv2d(img, w, padding=1))


def time_calibration(repeats: int = 5) -> float:
    """Median wall seconds of :func:`calibration_workload` (one warm-up call first)."""
    calibration_workload()
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        calibration_workload()
        samples.append(time.perf_counter() - t0)
    return float(statistics.median(samples))


