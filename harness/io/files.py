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

**Inputs are never replaced.** Before a write starts and again just before its rename, the
destination's identity ``(st_dev, st_ino)`` (symlinks followed) is looked up among the files the
running command read (:func:`harness.io.safe.recording_inputs`): an input reached under any other
name — a symlinked folder, a hard link, a bind mount of its folder — is refused with one line naming
the output as given and the input. Commands that know their outputs up front call
:func:`refuse_inputs` before any work, so a refusal leaves nothing behind.

**Permissions.** ``mkstemp`` creates ``0600`` files; every output is given ``0666 & ~umask`` before
its rename (``0644`` under the usual umask ``022``), whether it is new or replaces a file, as a
plain ``open(path, "w")`` would create it: results, tables and a stage cache shared between users
or served by a web server are readable.

Failures are one :class:`~harness.core.errors.InputError` naming the destination the caller gave,
never the temporary file.
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


def umask() -> int:
    """The process umask, read without changing it (``/proc/self/status`` on Linux; elsewhere the
    set-and-restore idiom)."""
    try:
        with open("/proc/self/status", "rb") as f:
            for line in f:
                if line.startswith(b"Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    old = os.umask(0o022)
    os.umask(old)
    return old


def output_mode() -> int:
    """Permission bits of a new output: ``0666 & ~umask``."""
    return 0o666 & ~umask()


def _reason(err: OSError) -> str:
    """The first line of an OSError's reason (pyarrow's messages span lines and name no file)."""
    return err.strerror or (str(err).strip().splitlines() or [type(err).__name__])[0]


def refuse_inputs(*paths: str | Path) -> None:
    """InputError when one of ``paths`` is a file the running command read (by device and inode,
    so every alias of it counts); a path that does not exist is fine."""
    from harness.core.errors import InputError
    from harness.io.safe import input_named

    for path in paths:
        try:
            st = os.stat(path)
        except OSError:
            continue
        given = input_named(st)
        if given is not None:
            same = "" if os.path.abspath(given) == os.path.abspath(path) else " (the same file under another name)"
            raise InputError(path, f"would overwrite the input {given}{same}; choose another output")


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


def check_output_folder(folder: str | Path, source=None) -> None:
    """What :func:`make_output_folder` checks, creating nothing: an existing ``folder`` must be a
    folder that takes files; a missing one, creatable (its nearest existing ancestor a writable folder)."""
    from harness.core.errors import InputError

    folder = Path(folder)
    source = folder if source is None else source
    if folder.exists():
        if not folder.is_dir():
            raise InputError(source, "exists and is not a folder")
        probe_writable(folder, source)
        return
    parent = next(p for p in folder.absolute().parents if p.exists())
    if not parent.is_dir():
        raise InputError(source, f"cannot create the folder: {parent} is not a folder")
    probe_writable(parent, source)


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
    from harness.core.errors import STORAGE_ERRNOS, InputError, StorageFull

    path = Path(path)
    refuse_inputs(path)
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = temp_path(path)
        writer(tmp)
        with open(tmp, "rb+") as f:
            os.fchmod(f.fileno(), output_mode())
            os.fsync(f.fileno())
        refuse_inputs(path)  # again: the destination may have been replaced meanwhile
        os.replace(tmp, path)
    except OSError as err:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        if err.errno in STORAGE_ERRNOS:
            full = f"cannot write: {_reason(err)} (the storage is full or limits file sizes)"
            raise StorageFull(path, full) from None
        raise InputError(
            path, "is a folder" if isinstance(err, IsADirectoryError) else f"cannot write: {_reason(err)}"
        ) from None
    except BaseException:
        if tmp is not None:
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


def append_line(path: str | Path, line: str) -> Path:
    """Append one line to a log-like file (``history.jsonl``) with one ``write``: created
    ``0666 & ~umask`` when absent; a symlink, FIFO, device or folder in its place is refused rather
    than followed or blocked on, and an input of the running command is never appended to."""
    import stat

    from harness.core.errors import InputError

    path = Path(path)
    refuse_inputs(path)
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        st = None
    except OSError as err:
        raise InputError(path, f"cannot append: {_reason(err)}") from None
    if st is not None and not stat.S_ISREG(st.st_mode):
        from harness.io.safe import kind_of

        what = "a symlink" if stat.S_ISLNK(st.st_mode) else kind_of(st.st_mode)
        raise InputError(path, f"is {what}; expected a regular file to append to")
    flags = os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NONBLOCK | getattr(os, "O_NOFOLLOW", 0) \
        | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags, output_mode())
    except OSError as err:  # swapped for a symlink (ELOOP) or a FIFO without reader (ENXIO) meanwhile
        raise InputError(path, f"cannot append: {_reason(err)}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise InputError(path, "is not a regular file; refusing to append to it")
        data = line.encode("utf-8")
        if os.write(fd, data) != len(data):
            raise InputError(path, "short write (disk full?)")
        os.fsync(fd)
    except OSError as err:
        raise InputError(path, f"cannot append: {_reason(err)}") from None
    finally:
        os.close(fd)
    return path
