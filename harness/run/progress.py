"""Rich progress bars, one per stage, for ``harness run``.

On a terminal each stage gets a live bar (done/total, elapsed, eta). When stderr is not a terminal
(a log file, CI) the bars are off and each stage prints one line when it starts and one when it
ends, with its count and seconds, so a background run's log still shows where it is.
"""

from __future__ import annotations

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


class _Bar:
    def __init__(self, sp: StageProgress, name: str, task_id, total: int):
        self._sp, self._name, self._id, self._total = sp, name, task_id, total
        self._done, self._t0, self._next_log = 0, time.perf_counter(), 0.1

    def advance(self, n: int = 1) -> None:
        self._done += n
        self._sp._progress.advance(self._id, n)
        frac = self._done / max(self._total, 1)
        if self._sp.plain and frac >= self._next_log and self._done < self._total:
            self._sp.console.print(f"  {self._name}: {self._done}/{self._total} "
                                   f"({time.perf_counter() - self._t0:.0f} s)")
            self._next_log = frac + 0.1

    def finish(self) -> None:
        t = self._sp._progress.tasks[self._id]
        self._sp._progress.update(self._id, completed=t.total)
        if self._sp.plain:
            self._sp.console.print(f"  {self._name}: done {self._done}/{self._total} in "
                                   f"{time.perf_counter() - self._t0:.1f} s")


class StageProgress:
    """``with StageProgress(console) as sp: bar = sp.stage("score", total); bar.advance()``."""

    def __init__(self, console: Console | None = None):
        self.console = console or Console(stderr=True)
        self.plain = not self.console.is_terminal
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
            self.console.print(f"{name}: {total} to compute")
        return _Bar(self, name, self._progress.add_task(name, total=max(total, 0)), total)
