"""The one error type a user sees: bad input, reported as one line, exit status 2."""

from __future__ import annotations

from pathlib import Path


class InputError(Exception):
    """Bad user input (file, config, argument). ``str(err)`` is the one-line message.

    ``source`` names the file (or config key, or argument) and ``problem`` says what is wrong.
    The CLI prints ``harness: <source>: <problem>`` to stderr and exits with status 2.
    """

    exit_status = 2

    def __init__(self, source: str | Path | None, problem: str):
        self.source = None if source is None else str(source)
        self.problem = " ".join(str(problem).split())  # always a single line
        super().__init__(self.problem if self.source is None else f"{self.source}: {self.problem}")

    def __reduce__(self):  # raised in a pool worker or Ray task, it travels back whole
        return (self.__class__, (self.source, self.problem))
