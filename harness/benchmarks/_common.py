"""Shared helpers for benchmarks: timing, peak memory, machine description, result files."""

from __future__ import annotations

import json
import os
import platform
import resource
import statistics
import time
from contextlib import contextmanager
from pathlib import Path

from harness.core.paths import results_dir


def machine() -> dict:
    """What the numbers were measured on."""
    import torch

    return {
        "platform": platform.platform(),
        "python": platform.python_version(),
        "cpus": os.cpu_count(),
        "torch": torch.__version__,
        "torch_threads": torch.get_num_threads(),
        "cuda": torch.cuda.get_device_name(0) if torch.cuda.is_available() else None,
    }


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far (MiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


@contextmanager
def stopwatch(out: dict, key: str):
    """``with stopwatch(times, "read"): ...`` stores the elapsed seconds in ``times["read"]``."""
    t0 = time.perf_counter()
    try:
        yield
    finally:
        out[key] = time.perf_counter() - t0


def median_time(fn, repeats: int = 3) -> tuple[float, list[float]]:
    """Median wall seconds of ``fn()`` over ``repeats`` calls, and all samples."""
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples), samples


def write_result(name: str, payload: dict, markdown: str | None = None) -> Path:
    """Write ``results/bench/<name>.json`` (with the machine description) and optional ``.md``."""
    out = results_dir() / "bench"
    out.mkdir(parents=True, exist_ok=True)
    payload = {"benchmark": name, "when": time.strftime("%Y-%m-%dT%H:%M:%S"), "machine": machine(), **payload}
    path = out / f"{name}.json"
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(payload, indent=2, default=float) + "\n")
    tmp.replace(path)
    if markdown is not None:
        (out / f"{name}.md").write_text(markdown.rstrip() + "\n")
    return path
