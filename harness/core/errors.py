"""The one error type a user sees: bad input, reported as one line, exit status 2.

:class:`HarnessError` is what the Python API (``harness.prune`` ...) raises and the command line
prints; :class:`InputError`, bad input, is the kind raised everywhere today. Both are
``<source>: <problem>`` on one line. The API names its keyword arguments as sources (``ratio``),
the command line its flags (``--ratio``): a command calls the API inside :func:`naming`, which
renames the source and keeps the problem, so both say the same thing about the same mistake.
"""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Iterator, Mapping


def printable(text: str) -> str:
    """``text`` with every character that is not printable (ESC, NUL, bidi overrides, …) written as its
    escape (``\\x1b``): a message quoting a file or scene name never drives the terminal it is printed on."""
    if text.isprintable():
        return text
    return "".join(ch if ch.isprintable() else f"\\x{ord(ch):02x}" if ord(ch) < 256 else f"\\u{ord(ch):04x}"
                   for ch in text)


class HarnessError(Exception):
    """An error with a one-line message. ``str(err)`` is the line the CLI prints after ``harness: ``.

    ``source`` names the file (or config key, or argument) and ``problem`` says what is wrong.
    The CLI prints ``harness: <source>: <problem>`` to stderr and exits with status 2.
    """

    exit_status = 2

    def __init__(self, source: str | Path | None, problem: str):
        self.source = None if source is None else printable(str(source))
        self.problem = printable(" ".join(str(problem).split()))  # always a single line
        super().__init__(self.problem if self.source is None else f"{self.source}: {self.problem}")

    def __reduce__(self):  # raised in a pool worker or Ray task, it travels back whole
        return (self.__class__, (self.source, self.problem))


class InputError(HarnessError):
    """Bad user input (file, config, argument)."""


class StorageFull(InputError):
    """A write failed because the storage is full (no space, a file-size limit, a quota): every later
    write would fail too, so a run stops at the first one instead of recording it against one task;
    what was stored before stays (the stage cache keeps it for the rerun)."""


#: errno values that say the storage, not the file, is the problem
STORAGE_ERRNOS = frozenset({28, 27, 122})  # ENOSPC, EFBIG, EDQUOT


def task_error(err: BaseException) -> str:
    """``"<type>: <message>"``, how a task records an error of its own and goes on — except
    :class:`StorageFull`, re-raised: a full disk is the run's end, not one task's failure."""
    if isinstance(err, StorageFull):
        raise err
    return f"{type(err).__name__}: {err}"


@contextmanager
def naming(names: Mapping[str, str]) -> Iterator[None]:
    """Errors raised inside whose source is a key of ``names`` are re-raised naming ``names[source]``
    instead (same class, same problem): ``with naming({"ratio": "--ratio"}): harness.api.prune(...)``."""
    try:
        yield
    except HarnessError as err:
        if err.source not in names:
            raise
        raise err.__class__(names[err.source], err.problem) from None
