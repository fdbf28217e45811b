"""Where the stage cache's bytes live: a folder (:class:`LocalStore`) or an fsspec URL
(:class:`FsspecStore`). A store reads, writes, deletes and tests relative paths
(``stage/ab/key.ext``); it knows nothing of keys or checksums (:mod:`harness.run.cache.entries`).

**Reads are bounded** like every other read of the tool (:mod:`harness.io.safe`): an entry must be
a regular file — opened with ``O_NOFOLLOW | O_NONBLOCK`` and ``fstat``-ed, so a symlink (to
``/dev/zero`` or anywhere), a FIFO, a device or a folder in an entry's place is reported as a
:class:`BadEntry` (then discarded and recomputed by the cache) instead of being followed, blocked
on or read without end — and at most the ``array`` size cap is read (an object store is asked
for a byte range of that length).

**Writes are atomic**: a folder's entries through :func:`harness.io.files.atomic_write_bytes`
(temp + fsync + rename; ``0666 & ~umask``); an object store's by one PUT (``pipe_file``), visible
only once complete. ``file://PATH`` is the folder ``PATH``.
"""

from __future__ import annotations

import errno
import hashlib
import os
import stat
from pathlib import Path

from harness.core.errors import InputError
from harness.io.files import atomic_write_bytes


class BadEntry(Exception):
    """An entry that cannot be what the cache wrote (not a regular file, too large, unreadable)."""


def _entry_cap() -> int:
    from harness.io.safe import limit

    return limit("array")


def is_url(location) -> bool:
    """Whether a cache location is an fsspec URL (``proto://...``) rather than a folder."""
    return isinstance(location, str) and "://" in location


class LocalStore:
    """Byte storage of the cache under a local folder (or one every node mounts: NFS, CephFS ...)."""

    process_local = False

    def __init__(self, root: str | Path):
        self.root = Path(root)

    def path(self, rel: str) -> Path:
        return self.root / rel

    def read(self, rel: str) -> bytes | None:
        """The entry's bytes; None when absent; :class:`BadEntry` when something else is there."""
        from harness.io.safe import kind_of

        flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
        try:
            fd = os.open(self.root / rel, flags)
        except (FileNotFoundError, NotADirectoryError):
            return None
        except OSError as err:
            if err.errno == errno.ELOOP:
                raise BadEntry("is a symlink; entries are regular files") from None
            raise BadEntry(f"cannot read: {err.strerror or err}") from None
        try:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode):
                raise BadEntry(f"is {kind_of(st.st_mode)}; entries are regular files")
            cap = _entry_cap()
            if st.st_size > cap:
                raise BadEntry(f"is {st.st_size:,} bytes, more than the {cap:,}-byte limit of an entry")
            with os.fdopen(os.dup(fd), "rb") as f:
                return f.read(st.st_size + 1)  # never read(cap): read(n) allocates n bytes
        except OSError as err:
            raise BadEntry(f"cannot read: {err.strerror or err}") from None
        finally:
            os.close(fd)

    def write(self, rel: str, data: bytes) -> None:
        atomic_write_bytes(self.root / rel, data)

    def delete(self, rel: str) -> None:
        """Remove an entry's name (a symlink itself, never its target; an empty folder)."""
        p = self.root / rel
        try:
            p.unlink()
        except FileNotFoundError:
            pass
        except (IsADirectoryError, PermissionError):
            try:
                p.rmdir()
            except OSError:
                pass

    def exists(self, rel: str) -> bool:
        return (self.root / rel).is_file()


class FsspecStore:
    """Byte storage of the cache under an fsspec URL (object stores: s3://, gs://; memory://).

    ``write`` is a single ``pipe_file`` (one PUT: atomic per object); ``read`` is a ranged
    ``cat_file`` (no listing cache is consulted, so an entry written by another node is seen at once).
    Files that other code opens by path (PNG images copied into a run folder) are downloaded into
    ``mirror``. The backend's package must be installed on every node (``s3fs`` for s3://)."""

    def __init__(self, url: str, mirror: Path):
        import fsspec

        self.url = url.rstrip("/")
        try:
            self.fs, self.base = fsspec.core.url_to_fs(self.url)
        except ImportError as err:  # s3:// without s3fs, gs:// without gcsfs ...
            raise InputError(url, f"its storage backend is not installed ({' '.join(str(err).split())[:160]})") \
                from None
        except (ValueError, TypeError, OSError) as err:  # an unknown protocol, a malformed URL
            raise InputError(url, f"not a usable cache location ({' '.join(str(err).split())[:160]})") from None
        self.base = self.base.rstrip("/")
        self.mirror = Path(mirror)

    @property
    def process_local(self) -> bool:
        """Whether the storage exists only inside this process (``memory://``): other processes —
        pool workers, Ray tasks — would each see their own empty store."""
        protocols = self.fs.protocol if isinstance(self.fs.protocol, tuple) else (self.fs.protocol,)
        return "memory" in protocols

    def _p(self, rel: str) -> str:
        return f"{self.base}/{rel}"

    def path(self, rel: str) -> Path:
        """A local copy of the entry (fetched now; a path that does not exist when it is absent)."""
        local = self.mirror / rel
        data = self.read(rel)
        if data is not None:
            atomic_write_bytes(local, data)
        return local

    def read(self, rel: str) -> bytes | None:
        cap = _entry_cap()
        try:
            data = self.fs.cat_file(self._p(rel), start=0, end=cap + 1)
        except (FileNotFoundError, NotADirectoryError):
            return None
        except IsADirectoryError:
            raise BadEntry("is a folder; entries are objects") from None
        if len(data) > cap:
            raise BadEntry(f"is more than the {cap:,}-byte limit of an entry")
        return data

    def write(self, rel: str, data: bytes) -> None:
        self.fs.pipe_file(self._p(rel), bytes(data))

    def delete(self, rel: str) -> None:
        try:
            self.fs.rm_file(self._p(rel))
        except (FileNotFoundError, IsADirectoryError):
            pass

    def exists(self, rel: str) -> bool:
        self.fs.invalidate_cache(self._p(rel))  # s3fs/gcsfs cache listings: ask the store itself
        return self.fs.isfile(self._p(rel))


def open_store(location: str | Path) -> tuple[LocalStore | FsspecStore, Path]:
    """(store, local root) of a cache location: a folder, ``file://FOLDER``, or an fsspec URL (its
    local root is a mirror folder under the harness cache, for the files opened by path)."""
    if is_url(location) and not str(location).startswith("file://"):
        from harness.core.paths import cache_dir

        mirror = cache_dir() / "mirror" / hashlib.sha256(str(location).encode()).hexdigest()[:16]
        return FsspecStore(str(location), mirror), mirror
    root = Path(str(location)[len("file://"):] if is_url(location) else location)
    return LocalStore(root), root
