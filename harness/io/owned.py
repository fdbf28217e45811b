"""One command owns an output folder while it writes it, and what it writes appears as one step.

**The lock.** ``harness run``, ``harness tables`` and ``harness report`` take ``<folder>/.harness.lock``
(``flock``, exclusive) before they write anything there, and hold it to the end; a second one is
refused with one line naming the holder (the command, its PID and host, since when), which the
holder writes into the file. The kernel releases the lock when its process ends, however it ends: a
``kill -9`` leaves the file, unlocked, and the next command simply takes it — no stale lock to clear
by hand, no PID guessing. ``harness track`` reads a run folder under the same lock, shared.

**Staging and publishing.** The owner writes what it publishes into ``<folder>/.harness-staging/``;
what it only reads or extends from the folder (the records of earlier runs, the renders a rebuilt
page shows) is first *carried* there as hard links (copies where the file system refuses links), so
the staging folder is the folder as it will be. :meth:`OwnedFolder.publish` then writes the list of
entries into it and renames it ``.harness-publishing`` — from that rename on, the publication is
decided — and moves each entry into place: a file with one atomic rename over the old one, a folder
by moving the old one aside into ``.harness-publishing/.replaced/`` and the new one in. What was
replaced is deleted last. Killed before the decision, the next owner deletes the staging folder and
the folder holds the earlier outputs, whole; killed after it, the next owner (of any of the three
commands) finishes the moves first: the folder holds one publication or the next, never files of
two. A reader outside the harness that reads while a publication moves its entries (a few renames)
can find a folder entry missing for that moment, never one of another run.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import socket
import stat
import time
from pathlib import Path

from harness.core.errors import InputError

LOCK = ".harness.lock"
STAGING = ".harness-staging"
PUBLISHING = ".harness-publishing"
_ENTRIES = ".entries.json"
_REPLACED = ".replaced"


def _holder(fd: int) -> str:
    """Who holds the lock, from what it wrote into the lock file."""
    try:
        info = json.loads(os.pread(fd, 4096, 0).decode("utf-8") or "{}")
        return (f"{info['command']} (pid {info['pid']} on {info['host']}, since {info['since']})"
                if isinstance(info, dict) and {"command", "pid", "host", "since"} <= info.keys() else "another command")
    except (OSError, ValueError, UnicodeDecodeError):
        return "another command"


def _lock(path: Path, fd: int, shared: bool) -> None:
    import fcntl

    try:
        fcntl.flock(fd, (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = _holder(fd)
        os.close(fd)
        raise InputError(path, f"is being written by {holder}; wait for it to finish, or choose another output "
                               "folder") from None
    except OSError as err:
        os.close(fd)
        raise InputError(path, f"cannot be locked for writing: {err.strerror or err}") from None


def _carry(src: Path, dst: Path) -> None:
    """``src`` at ``dst``: a folder entry by entry, a file or a symlink (itself, not its target) as a
    hard link, a copy where links are refused; anything else (a FIFO, a device) is refused, as the
    readers of what is carried would refuse it."""
    from harness.io.safe import kind_of

    st = os.lstat(src)
    if stat.S_ISDIR(st.st_mode):
        dst.mkdir()
        for child in src.iterdir():
            _carry(child, dst / child.name)
    elif stat.S_ISREG(st.st_mode) or stat.S_ISLNK(st.st_mode):
        try:
            os.link(src, dst, follow_symlinks=False)
        except OSError:
            if stat.S_ISLNK(st.st_mode):
                os.symlink(os.readlink(src), dst)
            else:
                shutil.copy2(src, dst)
    else:
        raise InputError(src, f"is {kind_of(st.st_mode)}; expected a regular file")


def _move_in(src: Path, dst: Path, replaced: Path) -> None:
    """``src`` in place of ``dst``: a file over a file in one rename, else the old one moved aside first."""
    if src.is_file() and not src.is_symlink() and (dst.is_file() or not os.path.lexists(dst)):
        os.replace(src, dst)
        return
    if os.path.lexists(dst):
        replaced.mkdir(exist_ok=True)
        os.replace(dst, replaced / dst.name)
    os.replace(src, dst)


def _files(path: Path):
    """Every file under ``path`` (itself, when it is not a folder)."""
    if path.is_dir() and not path.is_symlink():
        for root, _, files in os.walk(path):
            yield from (Path(root) / f for f in files)
    elif os.path.lexists(path):
        yield path


def _inode(path: Path):
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def _refuse_inputs_under(paths, staged) -> None:
    """InputError when a file under ``paths`` (the entries a publication replaces and deletes) is one
    this command read: an input is never deleted, whatever folder it sits in. A file carried into the
    publication (the same inode under ``staged``: an earlier run's record the page read) is not
    deleted but moved with it, and passes."""
    from harness.io.files import refuse_inputs

    kept = {_inode(f) for path in staged for f in _files(path)}
    refuse_inputs(*(f for path in paths for f in _files(path) if _inode(f) not in kept))


class OwnedFolder:
    """An output folder held by one command (module docstring): ``with OwnedFolder(out, "harness run")
    as folder: stage = folder.stage(carry=("records",)) … folder.publish([...])``."""

    def __init__(self, path: str | Path, command: str, source=None, *, owns=(), create: bool = True):
        self.path = Path(path)
        self.command = command
        self.source = self.path if source is None else source
        self.owns = tuple(owns)  # the entries it will replace: refused at once when the folder is not a run's
        self.create = create  # False: a folder that must exist already (a run folder to rebuild)
        self._fd: int | None = None
        self._staging: Path | None = None

    # ------------------------------------------------------------------ the lock
    def __enter__(self) -> OwnedFolder:
        from harness.io.files import make_output_folder, output_mode

        if not self.create and not self.path.is_dir():
            raise InputError(self.source, "no such folder" if not self.path.exists() else "is not a folder")
        make_output_folder(self.path, self.source)
        lock = self.path / LOCK
        self._claim()
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, output_mode())
        except OSError as err:
            raise InputError(self.source, f"cannot create its lock file {LOCK}: {err.strerror or err}") from None
        _lock(self.source, fd, shared=False)
        self._fd = fd
        me = {"command": self.command, "pid": os.getpid(), "host": socket.gethostname(),
              "since": time.strftime("%Y-%m-%d %H:%M:%S")}
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps(me, allow_nan=False).encode(), 0)
        self.recover()
        return self

    def _claim(self) -> None:
        """Refuse, before any work, to replace entries of a folder no owner held before: a run into
        ``--out .`` must not swap away the user's own ``images/``."""
        present = [e for e in self.owns if os.path.lexists(self.path / e)]
        # ours: a folder an owner held before (its lock file), or a run folder of older code (its results)
        ours = any(os.path.lexists(self.path / f) for f in (LOCK, "run.json", "results.parquet"))
        if present and not ours:
            raise InputError(self.source, f"holds {', '.join(present[:3])} but is not a harness run folder: a run "
                                          f"replaces its {', '.join(self.owns)}; choose an empty or new folder")

    def __exit__(self, *exc) -> None:
        if self._staging is not None:
            shutil.rmtree(self._staging, ignore_errors=True)
        if self._fd is not None:
            os.close(self._fd)  # releases the lock
            self._fd = None

    # ------------------------------------------------------------------ staging and publishing
    def recover(self) -> None:
        """Finish a publication a killed owner had decided; drop one it had not (module docstring)."""
        shutil.rmtree(self.path / STAGING, ignore_errors=True)
        pub = self.path / PUBLISHING
        if not pub.is_dir():
            return
        try:
            entries = json.loads((pub / _ENTRIES).read_text())
        except (OSError, ValueError):
            entries = []
        for name in entries:
            if os.path.lexists(pub / name):
                _move_in(pub / name, self.path / name, pub / _REPLACED)
        shutil.rmtree(pub, ignore_errors=True)

    def stage(self, carry=()) -> Path:
        """A fresh staging folder holding the entries ``carry`` of the folder (as hard links)."""
        staging = self.path / STAGING
        shutil.rmtree(staging, ignore_errors=True)
        staging.mkdir()
        self._staging = staging
        for name in carry:
            if os.path.lexists(self.path / name):
                _carry(self.path / name, staging / name)
        return staging

    def publish(self, entries) -> None:
        """Put the staged ``entries`` (names directly under the folder) in place as one publication."""
        staging, pub = self._staging, self.path / PUBLISHING
        if staging is None:
            raise RuntimeError("publish() before stage()")
        entries = [e for e in entries if os.path.lexists(staging / e)]
        _refuse_inputs_under([self.path / e for e in entries], [staging / e for e in entries])
        try:
            with open(staging / _ENTRIES, "w") as f:
                json.dump(entries, f, allow_nan=False)
                f.flush()
                os.fsync(f.fileno())
            os.replace(staging, pub)  # the decision
        except OSError as err:
            raise InputError(self.source, f"cannot publish: {err.strerror or err}") from None
        self._staging = None
        self.recover()  # the moves, and the deletion of what they replaced

    def final(self, path: Path) -> Path:
        """Where a staged path ends up once published."""
        try:
            return self.path / Path(path).relative_to(self.path / STAGING)
        except ValueError:
            return Path(path)


def reading(path: str | Path):
    """A context in which ``path``, a run folder, is read under the owners' lock (shared): refused
    while a command writes it. A folder no owner ever locked (no lock file) is read as it is."""
    from contextlib import contextmanager

    @contextmanager
    def held():
        lock = Path(path) / LOCK
        try:
            fd = os.open(lock, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
        except OSError as err:
            if err.errno not in (errno.ENOENT, errno.ENOTDIR, errno.EACCES):
                raise InputError(path, f"cannot read its lock file {LOCK}: {err.strerror or err}") from None
            yield
            return
        _lock(Path(path), fd, shared=True)
        try:
            yield
        finally:
            os.close(fd)
    return held()
