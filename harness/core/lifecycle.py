"""Process lifecycle: signals become exceptions, and pool workers die with their parent.

* :func:`install_signal_handlers` (the CLI calls it): SIGTERM and SIGHUP raise :class:`Terminated`
  in the main thread, like Ctrl-C raises ``KeyboardInterrupt``, so every ``finally``/``except
  BaseException`` runs — an interrupted atomic write removes its temporary file, a run terminates
  its process pool — and the CLI exits with 128 + the signal number after one line.
* :func:`die_with_parent` (the pool initializer calls it): on Linux ``prctl(PR_SET_PDEATHSIG,
  SIGKILL)``, so a worker is killed by the kernel when the process that started it dies, even by
  ``kill -9`` (which no handler sees). Elsewhere it is a no-op; the driver's handler still
  terminates the pool on SIGTERM/SIGINT.
"""

from __future__ import annotations

import os
import signal
import sys


class Terminated(BaseException):
    """Raised in the main thread by SIGTERM/SIGHUP (a BaseException, like KeyboardInterrupt)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _raise(signum, frame):
    raise Terminated(signum)


def install_signal_handlers() -> None:
    for sig in (signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if sig is not None:
            try:
                signal.signal(sig, _raise)
            except (ValueError, OSError):  # not the main thread / not supported
                pass


_PR_SET_PDEATHSIG = 1


def die_with_parent(parent_pid: int | None = None) -> bool:
    """Ask the kernel to SIGKILL this process when its parent exits (Linux); True when set.

    ``parent_pid``: the parent expected; if it already exited before the request was made, exit now."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) != 0:
            return False
    except (OSError, AttributeError):
        return False
    if parent_pid is not None and os.getppid() != parent_pid:
        os._exit(1)  # the parent died before the request: nobody is waiting for this worker
    return True
