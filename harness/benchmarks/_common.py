"""Shared helpers for benchmarks: timing, peak memory, machine description, result files."""

from __future__ import annotations

import json
import resource
import statistics
import time
from contextlib import contextmanager
from pathlib import Path

from harness.core.paths import results_dir
from harness.io.files import atomic_write_text
from harness.report.machine import describe_machine


def require(module: str, purpose: str):
    """Import a benchmark-only dependency, or say how to install it (one line, exit 2)."""
    import importlib

    from harness.core.errors import InputError

    try:
        return importlib.import_module(module)
    except ImportError:
        raise InputError(module, f"{purpose} needs it; install the bench extra: pip install -e '.[bench]'") from None


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


def write_result(name: str, payload: dict, markdown: str | None = None, folder: Path | None = None) -> Path:
    """Write ``<folder>/<name>.json`` (with the machine description) and optional ``.md``; ``folder``
    defaults to ``results/bench``."""
    out = Path(folder) if folder is not None else results_dir() / "bench"
    out.mkdir(parents=True, exist_ok=True)
    payload = {"benchmark": name, "when": time.strftime("%Y-%m-%dT%H:%M:%S"), "machine": describe_machine(), **payload}
    path = out / f"{name}.json"
    atomic_write_text(path, json.dumps(payload, indent=2, default=float) + "\n")
    if markdown is not None:
        atomic_write_text(out / f"{name}.md", markdown.rstrip() + "\n")
    return path
