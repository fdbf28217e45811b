"""Writing files so that nothing half-written is ever seen: one atomic-write path for the house.

Every output (scenes, cache entries, tables, images, run records) is produced in a temporary file
in the destination's own folder, flushed and fsynced, then renamed over the destination with
``os.replace`` — atomic on POSIX, so a reader (or a rerun after ``kill -9``) finds either the old
file, the complete new one, or nothing. A failure or an exception removes the temporary file.

Temporary names are ``.<name>.<host>.<pid>.<random>.tmp``: host and PID say which process owns
one, so files left by a process that was killed (``kill -9`` cannot be caught) are recognised and
removed by :func:`sweep_stale_temps`, which every command runs on the folders it writes when it
starts: a temporary file of this host whose PID is not running is removed at once; one of another
host (a cache folder shared between nodes) only once it is older than :data:`STALE_AFTER_S`.
SIGTERM and SIGINT are turned into exceptions by the CLI, so the ``except`` below removes the
temporary file of a write they interrupt.
"""

from __future__ import annotations

import os
import re
import socket
import tempfile
import time
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

TMP_SUFFIX = ".tmp"
#: a temporary file of another host is swept only when older than this (it may still be written)
STALE_AFTER_S = 24 * 3600


def _host() -> str:
    return re.sub(r"[^A-Za-z0-9-]", "-", socket.gethostname())[:40] or "host"


def temp_path(path: Path) -> Path:
    """A fresh, unique temporary file beside ``path`` (created empty, owned by this process)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.{_host()}.{os.getpid()}.", suffix=TMP_SUFFIX)
    os.close(fd)
    return Path(tmp)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def stale_temp(p: Path, now: float | None = None) -> bool:
    """Whether ``p`` is a temporary file of this module left by a process that is gone."""
    name = p.name
    if not (name.startswith(".") and name.endswith(TMP_SUFFIX)):
        return False
    parts = name[1:-len(TMP_SUFFIX)].split(".")
    if len(parts) < 3 or not parts[-2].isdigit():
        return False
    pid, host = int(parts[-2]), parts[-3]
    if host == _host():
        return not _pid_alive(pid)
    try:
        age = (now or time.time()) - p.lstat().st_mtime
    except OSError:
        return False
    return age > STALE_AFTER_S


def sweep_stale_temps(folder: str | Path, recursive: bool = False) -> int:
    """Remove the temporary files left in ``folder`` by killed processes; returns how many."""
    folder = Path(folder)
    if not folder.is_dir():
        return 0
    removed = 0
    try:
        candidates = folder.rglob(".*" + TMP_SUFFIX) if recursive else folder.glob(".*" + TMP_SUFFIX)
        for p in candidates:
            if stale_temp(p):
                try:
                    p.unlink()
                    removed += 1
                except OSError:
                    pass
    except OSError:
        pass
    return removed


def probe_writable(folder: str | Path, source=None) -> None:
    """Refuse (InputError) a folder that cannot take a new file: missing, not a folder, read-only,
    a pseudo-filesystem such as /proc. Checked by creating and removing a temporary file, since
    permission bits say nothing for root or a read-only mount."""
    from harness.core.errors import InputError

    folder = Path(folder)
    source = folder if source is None else source
    if not folder.exists():
        raise InputError(source, "output folder does not exist")
    if not folder.is_dir():
        raise InputError(source, "exists and is not a folder")
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".probe.{_host()}.{os.getpid()}.", suffix=TMP_SUFFIX)
        os.close(fd)
        os.unlink(tmp)
    except OSError as err:
        raise InputError(source, f"cannot write there: {err.strerror or err}") from None


def make_output_folder(folder: str | Path, source=None) -> Path:
    """Create ``folder`` (and parents) for output and check that it takes files; InputError otherwise."""
    from harness.core.errors import InputError

    folder = Path(folder)
    source = folder if source is None else source
    if folder.exists() and not folder.is_dir():
        raise InputError(source, "exists and is not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(source, f"cannot create the folder: {err.strerror or err}") from None
    probe_writable(folder, source)
    sweep_stale_temps(folder)
    return folder


def atomic_write_with(path: str | Path, writer: Callable[[Path], None]) -> Path:
    """Let ``writer(tmp_path)`` produce the file (pandas ``to_parquet``, ``fig.savefig`` ...), fsync
    it and rename it into place; returns ``path``. The parent folder is created when missing."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_path(path)
    try:
        writer(tmp)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def atomic_write_chunks(path: str | Path, chunks: Iterable[bytes | np.ndarray]) -> Path:
    """Write byte strings and numpy arrays (their raw bytes, ``tofile``) one after the other."""

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            for chunk in chunks:
                if isinstance(chunk, np.ndarray):
                    chunk.tofile(f)
                else:
                    f.write(chunk)

    return atomic_write_with(path, write)


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    return atomic_write_chunks(path, [data])


def atomic_write_text(path: str | Path, text: str) -> Path:
    return atomic_write_chunks(path, [text.encode("utf-8")])


def atomic_write_npy(path: str | Path, array: np.ndarray) -> Path:
    """``np.save`` through a file handle (a path not ending in .npy would get the suffix appended)."""

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            np.save(f, np.asarray(array), allow_pickle=False)

    return atomic_write_with(path, write)
