"""Progress of a study's stages: live bars on a terminal, lines through :mod:`logging` elsewhere.

Given a rich console that is a terminal (``harness run`` in a shell), each stage gets a live bar
(done/total, elapsed, eta). Otherwise — a log file, CI, or a library call (``harness.evaluate``),
which is given no console and must not print — each stage is logged (logger ``harness.run``, level
INFO) when it starts, at every tenth of its work and when it ends, with its count and seconds, so
a background run's log still shows where it is; ``harness run`` shows these records on stderr.
"""

from __future__ import annotations

import logging
import time

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

log = logging.getLogger("harness.run")


class _Bar:
    def __init__(self, sp: StageProgress, name: str, task_id, total: int):
        self._sp, self._name, self._id, self._total = sp, name, task_id, total
        self._done, self._t0, self._next_log = 0, time.perf_counter(), 0.1

    def advance(self, n: int = 1) -> None:
        self._done += n
        self._sp._progress.advance(self._id, n)
        frac = self._done / max(self._total, 1)
        if self._sp.plain and frac >= self._next_log and self._done < self._total:
            log.info("  %s: %d/%d (%.0f s)", self._name, self._done, self._total, time.perf_counter() - self._t0)
            self._next_log = frac + 0.1

    def finish(self) -> None:
        t = self._sp._progress.tasks[self._id]
        self._sp._progress.update(self._id, completed=t.total)
        if self._sp.plain:
            log.info("  %s: done %d/%d in %.1f s", self._name, self._done, self._total,
                     time.perf_counter() - self._t0)


class StageProgress:
    """``with StageProgress(console) as sp: bar = sp.stage("score", total); bar.advance()``; without
    a console (or with one that is no terminal) the stages are logged instead of drawn."""

    def __init__(self, console: Console | None = None):
        self.plain = console is None or not console.is_terminal
        self.console = console or Console(stderr=True, quiet=True)
        self._progress = Progress(
            TextColumn("[bold]{task.description:<16}"), BarColumn(), MofNCompleteColumn(),
            TimeElapsedColumn(), TextColumn("eta"), TimeRemainingColumn(),
            console=self.console, transient=False, disable=self.plain,
        )

    def __enter__(self):
        self._progress.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        self._progress.__exit__(*exc)

    def stage(self, name: str, total: int) -> _Bar:
        if self.plain:
            log.info("%s: %d to compute", name, total)
        return _Bar(self, name, self._progress.add_task(name, total=max(total, 0)), total)
