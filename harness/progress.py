"""Rich progress bars, one per stage, for ``harness run`` (silent when not a terminal)."""

from __future__ import annotations

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
    def __init__(self, progress: Progress, task_id):
        self._p, self._id = progress, task_id

    def advance(self, n: int = 1) -> None:
        self._p.advance(self._id, n)

    def finish(self) -> None:
        t = self._p.tasks[self._id]
        self._p.update(self._id, completed=t.total)


class StageProgress:
    """``with StageProgress(console) as sp: bar = sp.stage("score", total); bar.advance()``."""

    def __init__(self, console: Console | None = None):
        self.console = console or Console(stderr=True)
        self._progress = Progress(
            TextColumn("[bold]{task.description:<16}"), BarColumn(), MofNCompleteColumn(),
            TimeElapsedColumn(), TextColumn("eta"), TimeRemainingColumn(),
            console=self.console, transient=False, disable=not self.console.is_terminal,
        )

    def __enter__(self) -> StageProgress:
        self._progress.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        self._progress.__exit__(*exc)

    def stage(self, name: str, total: int) -> _Bar:
        return _Bar(self._progress, self._progress.add_task(name, total=max(total, 0)))
