"""Shared helpers for benchmarks: timing, peak memory, machine description, result files."""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

from harness.core import jsonout
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


def median_time(fn, repeats: int = 3) -> tuple[float, list[float]]:
    """Median wall seconds of ``fn()`` over ``repeats`` calls, and all samples."""
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples), samples


#: where ``harness bench`` writes unless ``--out`` says otherwise: git-ignored (``runs/``), so trying a
#: benchmark never rewrites the committed results; ``--out results/bench`` updates those
DEFAULT_OUT = Path("runs") / "bench"


def out_dir(args, sub: str = "") -> Path:
    """The benchmark's output folder: ``--out``, else :data:`DEFAULT_OUT` (``/ sub``); created and
    probed before any work (a file there, a read-only folder: one line, exit 2)."""
    from harness.io.files import make_output_folder

    given = getattr(args, "out", None)
    folder = Path(given) if given else DEFAULT_OUT / sub
    return make_output_folder(folder, f"--out {folder}" if given else folder)


def tracked_note(folder: Path) -> str:
    """`` (the committed results: review the diff)`` when ``folder`` is under the repository's
    ``results/``, else ``""``: a run that rewrites tracked files says so."""
    try:
        Path(folder).resolve().relative_to(results_dir().resolve())
    except ValueError:
        return ""
    return " (rewrote the committed results under results/: review the diff before committing)"


def write_result(name: str, payload: dict, markdown: str | None, out: Path) -> Path:
    """Write ``<out>/<name>.json`` (with the machine description) and optional ``.md``; prints where."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    payload = {"benchmark": name, "when": time.strftime("%Y-%m-%dT%H:%M:%S"), "machine": describe_machine(), **payload}
    path = out / f"{name}.json"
    atomic_write_text(path, jsonout.dumps(payload, indent=2) + "\n")
    if markdown is not None:
        atomic_write_text(out / f"{name}.md", markdown.rstrip() + "\n")
    print(f"bench: wrote {path}" + (" and .md" if markdown is not None else "") + tracked_note(out))
    return path


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_python(
    checkout: Path, code: str, args=(), env=None, timeout=600
) -> tuple[subprocess.CompletedProcess, float, float]:
    """Run ``code`` with ``checkout``'s interpreter in its root: (process, wall s, CPU s of the tree)."""
    from harness.core.errors import InputError

    exe = checkout / ".venv" / "bin" / "python"
    cmd = [str(exe if exe.exists() else sys.executable), "-c", code, *args]
    c0, t0 = _children_cpu(), time.perf_counter()
    proc = subprocess.run(cmd, cwd=checkout, capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, **(env or {})})
    wall, cpu = time.perf_counter() - t0, _children_cpu() - c0
    if proc.returncode not in (0, 1):  # 1: the run finished with errors recorded in its rows
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:] or ["(no output)"]
        raise InputError(str(checkout), f"{' '.join(args[:2]) or 'probe'} failed (exit {proc.returncode}): {tail[0]}")
    return proc, wall, cpu
