"""The executor contract: :class:`Stage` s in, each task's summary dict out; :class:`Bars` for progress."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any


def _one(task) -> int:
    return 1


def _never(task) -> bool:
    return False


@dataclass
class Stage:
    """Tasks of one stage: ``fn(task) -> summary dict``, each worth ``weight(task)`` progress units;
    ``on_device(task)``: the task computes on the run's device (a GPU run sends it to a worker that
    holds the device, :mod:`harness.run.executors.device`)."""

    name: str
    fn: Callable
    tasks: list
    weight: Callable[[Any], int] = _one
    on_device: Callable[[Any], bool] = _never


class Bars:
    """Progress of several stages: ``start(name, total)``, ``advance(name, n)``, ``finish(name)``
    over a :class:`harness.run.progress.StageProgress` (or nothing)."""

    def __init__(self, progress=None):
        self.progress = progress
        self._bars: dict[str, Any] = {}

    def start(self, name: str, total: int) -> None:
        if self.progress is not None:
            self._bars[name] = self.progress.stage(name, total)

    def advance(self, name: str, n: int = 1) -> None:
        if name in self._bars and n:
            self._bars[name].advance(n)

    def finish(self, name: str) -> None:
        if name in self._bars:
            self._bars.pop(name).finish()


class Executor(ABC):
    """Runs stages; :meth:`run` returns each stage's task summaries (completion order)."""

    name = "executor"
    #: whether tasks run concurrently (the runner then orders them longest first)
    parallel = False

    @abstractmethod
    def run(self, stages: Sequence[Stage], bars: Bars) -> list[list[dict]]:
        """Every task of ``stages`` run once; per stage, the tasks' summary dicts."""

    def describe(self) -> dict:
        return {"name": self.name}

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


