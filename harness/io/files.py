"""Writing files so that nothing half-written is ever seen: one atomic-write path for the house.

Every output (scenes, cache entries, tables, images, run records) is produced in a temporary file
in the destination's own folder, flushed and fsynced, then renamed over the destination with
``os.replace`` — atomic on POSIX, so a reader (or a rerun after ``kill -9``) finds either the old
file, the complete new one, or nothing. A failure or an exception removes the temporary file.

Temporary names are ``.<name>.<pid>.<random>.tmp``: the PID says which process owns one, so files
left by a process that no longer exists can be recognised and swept.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

TMP_SUFFIX = ".tmp"


def temp_path(path: Path) -> Path:
    """A fresh, unique temporary file beside ``path`` (created empty, owned by this process)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.{os.getpid()}.", suffix=TMP_SUFFIX)
    os.close(fd)
    return Path(tmp)


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
