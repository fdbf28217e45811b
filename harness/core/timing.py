"""Per-stage timers any computation can report to, and any caller can collect.

    with record_stages() as seconds:          # the caller (harness prune, a benchmark)
        scores = pruner.score(scene, ctx)     # inside: `with stage("descriptors"): ...`
    seconds -> {"descriptors": 0.41, ...}

Without an active :func:`record_stages` a :func:`stage` block costs one context-variable lookup.
"""

from __future__ import annotations

import contextvars
import time
from contextlib import contextmanager

_ACTIVE: contextvars.ContextVar[tuple | None] = contextvars.ContextVar("harness_stages", default=None)


@contextmanager
def record_stages(clock=time.perf_counter):
    """Collect seconds per stage name, measured by ``clock`` (wall time by default;
    ``time.process_time`` gives CPU seconds of all threads)."""
    times: dict[str, float] = {}
    token = _ACTIVE.set((times, clock))
    try:
        yield times
    finally:
        _ACTIVE.reset(token)


@contextmanager
def stage(name: str):
    """Add the block's duration to ``name`` in the active recorder, if any."""
    active = _ACTIVE.get()
    t0 = active[1]() if active else 0.0
    try:
        yield
    finally:
        if active:
            times, clock = active
            times[name] = times.get(name, 0.0) + clock() - t0
