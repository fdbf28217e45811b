"""Content-addressed, verified stage cache: every stage result is stored under the sha256 of its
inputs, with the sha256 of its own bytes, and is checked before it is used.

``key = sha256(canonical JSON of {stage, inputs, format})`` where the inputs name everything the
result depends on: scene file **content** digests (:class:`FileDigests`: every file is hashed on
every run, never trusted by size/mtime), method + resolved params, camera set (:func:`digest_json`
of the camera dicts), renderer / metric / pruner code versions
(:func:`harness.run.versions.code_digest` of their source files). Values live at
``<root>/<stage>/<key[:2]>/<key>.<ext>``.

**Verification.** An entry file is an envelope ``b"HCE1 " + sha256(payload) + b"\n" + payload``
(payload: JSON text, or ``.npy`` bytes). A read recomputes the checksum; then the caller's schema
check (:mod:`harness.run.verify`: length = splat count, prune counts ≤ input, finite metrics ...)
runs on the decoded value. An entry that fails either is **discarded** — a one-line warning,
the file deleted — and reads as a miss, so the stage recomputes it. Checksums detect corruption
and careless edits (a byte flipped, a number changed by hand); they are not a defence against a
user who rewrites an entry *and* its checksum on purpose.

**Atomic publish, many writers.** Entries are written to a temporary file in the destination's
folder (name ``.<name>.<host>.<pid>.<random>.tmp``), fsynced and renamed into place
(:mod:`harness.io.files`), so a reader — in this process, another worker, or another node sharing
the folder — sees the old entry, the complete new one, or none. Two writers of one key write the
same content (keys are content addresses of deterministic computations) and the last rename wins;
a reader that races a deletion of a bad entry sees a miss. All storage access goes through a store
(read / write / delete / exists of a relative path): :class:`LocalStore` for a folder (local, or a
shared filesystem every node of a cluster mounts: NFS, CephFS, Lustre — rename is atomic there
too), :class:`FsspecStore` for an fsspec URL (``s3://bucket/prefix``, ``gs://...``,
``memory://...``), where each entry is published by **one** PUT (``pipe_file``): object stores
make an object visible only once it is complete, so there is no temporary object and no
non-atomic copy+delete "rename". ``file://PATH`` is the folder ``PATH`` (a :class:`LocalStore`).

Hit/miss counts per stage are kept so a run can prove that a rerun recomputed nothing.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import sys
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from harness.io.files import atomic_write_bytes

_HASH_CHUNK = 1 << 20
#: part of every key: entries written by an older layout (no envelope) are never looked up
CACHE_FORMAT = 2
_MAGIC = b"HCE1 "
_HEADER = len(_MAGIC) + 64 + 1


def canonical_json(obj: Any) -> str:
    """Deterministic JSON: sorted keys, no spaces, floats via repr, numpy scalars/arrays as lists."""

    def default(o):
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, (set, frozenset)):
            return sorted(o)
        if isinstance(o, Path):
            return str(o)
        raise TypeError(f"cannot hash {type(o).__name__} in a cache key")

    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=default, allow_nan=True)


def digest_json(obj: Any) -> str:
    return hashlib.sha256(canonical_json(obj).encode()).hexdigest()


def digest_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def digest_mask(keep: np.ndarray) -> str:
    """Digest of a boolean keep mask (length + packed bits): equal masks give equal digests."""
    keep = np.asarray(keep, dtype=bool)
    h = hashlib.sha256(str(len(keep)).encode() + b":")
    h.update(np.packbits(keep).tobytes())
    return h.hexdigest()


# --------------------------------------------------------------------------- file digests
class FileDigests:
    """sha256 of files and folders, from their content on every run.

    Nothing is trusted across processes: a scene edited in place with its size and mtime restored
    gets a new digest. Within one process a file is hashed once per identity
    ``(path, size, mtime_ns, ctime_ns, inode, device)`` — ctime cannot be set back by a user —
    so the frames of a sequence or a camera file named twice are not re-read. ``hashed_bytes``
    counts what was read (the cost of hashing is reported by ``harness run``).
    """

    def __init__(self, index_path: Path | None = None):
        self.index_path = None  # kept for callers; digests are no longer memoised on disk
        self._memo: dict[tuple, str] = {}
        self.hashed_bytes = 0
        self.seconds = 0.0

    def _file(self, path: Path) -> str:
        import time

        from harness.io.safe import open_regular

        t0 = time.perf_counter()
        with open_regular(path, "scene", "input file") as f:
            st = os.fstat(f.fileno())
            ident = (str(Path(path).resolve()), st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino, st.st_dev)
            if ident in self._memo:
                return self._memo[ident]
            h = hashlib.sha256()
            while chunk := f.read(_HASH_CHUNK):
                h.update(chunk)
        self.hashed_bytes += st.st_size
        self.seconds += time.perf_counter() - t0
        self._memo[ident] = h.hexdigest()
        return self._memo[ident]

    def digest(self, path: str | Path) -> str:
        """Digest of a file, or of a folder (relative names + file digests, sorted)."""
        path = Path(path)
        if path.is_dir():
            items = sorted(p for p in path.rglob("*") if p.is_file())
            return digest_json([[str(p.relative_to(path)), self._file(p)] for p in items])
        return self._file(path)


# --------------------------------------------------------------------------- storage
def is_url(location) -> bool:
    """Whether a cache location is an fsspec URL (``proto://...``) rather than a folder."""
    return isinstance(location, str) and "://" in location


class LocalStore:
    """Byte storage of the cache under a local folder (the one place that touches the disk).

    Paths are relative (``stage/ab/key.ext``). ``write`` is atomic (temp + fsync + rename); ``read``
    returns None when absent. An fsspec-backed store implements the same four methods."""

    def __init__(self, root: str | Path):
        self.root = Path(root)

    def path(self, rel: str) -> Path:
        return self.root / rel

    def read(self, rel: str) -> bytes | None:
        try:
            with open(self.root / rel, "rb") as f:
                return f.read()
        except (FileNotFoundError, NotADirectoryError, IsADirectoryError):
            return None

    def write(self, rel: str, data: bytes) -> None:
        atomic_write_bytes(self.root / rel, data)

    def delete(self, rel: str) -> None:
        try:
            (self.root / rel).unlink()
        except FileNotFoundError:
            pass

    def exists(self, rel: str) -> bool:
        return (self.root / rel).is_file()


class FsspecStore:
    """Byte storage of the cache under an fsspec URL (object stores: s3://, gs://; memory://).

    ``write`` is a single ``pipe_file`` (one PUT: atomic per object, a reader sees the old object or
    the complete new one); ``read`` is ``cat_file`` (no listing cache is consulted, so an entry
    written by another node is seen at once). Files that other code opens by path (the PNG images
    copied into a run folder) are downloaded into ``mirror`` by :meth:`path`. The backend's own
    package must be installed on every node (``s3fs`` for s3://) with its credentials."""

    def __init__(self, url: str, mirror: Path):
        import fsspec

        self.url = url.rstrip("/")
        self.fs, self.base = fsspec.core.url_to_fs(self.url)
        self.base = self.base.rstrip("/")
        self.mirror = Path(mirror)

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
        try:
            return self.fs.cat_file(self._p(rel))
        except (FileNotFoundError, IsADirectoryError, NotADirectoryError):
            return None

    def write(self, rel: str, data: bytes) -> None:
        self.fs.pipe_file(self._p(rel), bytes(data))

    def delete(self, rel: str) -> None:
        try:
            self.fs.rm_file(self._p(rel))
        except FileNotFoundError:
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


def envelope(payload: bytes) -> bytes:
    return _MAGIC + hashlib.sha256(payload).hexdigest().encode() + b"\n" + payload


def open_envelope(data: bytes) -> tuple[bytes | None, str | None]:
    """(payload, None) when the checksum holds, else (None, what is wrong)."""
    if len(data) < _HEADER or not data.startswith(_MAGIC) or data[_HEADER - 1:_HEADER] != b"\n":
        return None, "no checksum header (truncated or not written by the cache)"
    payload = data[_HEADER:]
    if hashlib.sha256(payload).hexdigest().encode() != data[len(_MAGIC):_HEADER - 1]:
        return None, "checksum mismatch (the entry was changed or damaged after it was written)"
    return payload, None


def _warn_stderr(message: str) -> None:
    print(f"harness: warning: {message}", file=sys.stderr, flush=True)


Check = Callable[[Any], "str | None"]


# --------------------------------------------------------------------------- the cache
class StageCache:
    """Results keyed by content. ``get_*`` return None on a miss (or a discarded bad entry);
    ``put_*`` store atomically. ``check`` arguments are schema checks returning a problem or None."""

    def __init__(self, root: str | Path, force: bool = False, warn: Callable[[str], None] | None = None,
                 store: LocalStore | FsspecStore | None = None):
        """``root``: a folder, ``file://FOLDER`` or an fsspec URL (see :func:`open_store`)."""
        opened, self.root = open_store(root)
        #: what a worker is given to open the same cache (an absolute folder, or the URL)
        self.location = str(root) if isinstance(opened, FsspecStore) else str(self.root.absolute())
        self.force = force  # every lookup misses (results are recomputed and overwritten)
        self.root.mkdir(parents=True, exist_ok=True)
        self.store = store or opened
        self.files = FileDigests()
        self.hits: Counter = Counter()
        self.misses: Counter = Counter()
        self.discarded: list[str] = []  # "stage/key: problem" of every entry thrown away
        self.warn = warn or _warn_stderr

    @staticmethod
    def key(stage: str, **inputs) -> str:
        return digest_json({"stage": stage, "cache_format": CACHE_FORMAT, **inputs})

    @staticmethod
    def rel(stage: str, key: str, ext: str) -> str:
        return f"{stage}/{key[:2]}/{key}.{ext}"

    def path(self, stage: str, key: str, ext: str) -> Path:
        return self.store.path(self.rel(stage, key, ext))

    def _count(self, stage: str, hit: bool) -> None:
        (self.hits if hit else self.misses)[stage] += 1

    def discard(self, stage: str, key: str, ext: str, problem: str) -> None:
        """Delete a bad entry and say so in one line."""
        self.store.delete(self.rel(stage, key, ext))
        self.discarded.append(f"{stage}/{key[:12]}: {problem}")
        self.warn(f"stage cache {stage} entry {key[:12]}.{ext}: {problem}; discarded, it will be recomputed")

    def _read(self, stage: str, key: str, ext: str, decode, check: Check | None):
        data = self.store.read(self.rel(stage, key, ext))
        if data is None:
            return None
        payload, problem = open_envelope(data)
        value = None
        if problem is None:
            try:
                value = decode(payload)
            except (ValueError, TypeError, OSError, EOFError, RecursionError) as err:
                problem = f"undecodable ({type(err).__name__}: {str(err)[:80]})"
        if problem is None and check is not None:
            try:
                problem = check(value)
            except (KeyError, TypeError, ValueError, IndexError, AttributeError) as err:
                problem = f"does not match its schema ({type(err).__name__}: {str(err)[:80]})"
        if problem is not None:
            self.discard(stage, key, ext, problem)
            return None
        return value

    # JSON values ------------------------------------------------------------------
    def get_json(self, stage: str, key: str, count: bool = True, check: Check | None = None):
        value = None if self.force else self._read(stage, key, "json", _decode_json, check)
        if count:
            self._count(stage, value is not None)
        return value

    def put_json(self, stage: str, key: str, value) -> None:
        payload = json.dumps(value, allow_nan=True, default=float, sort_keys=True).encode()
        self.store.write(self.rel(stage, key, "json"), envelope(payload))

    # array values -------------------------------------------------------------------
    def get_array(self, stage: str, key: str, count: bool = True, check: Check | None = None) -> np.ndarray | None:
        value = None if self.force else self._read(stage, key, "npy", _decode_npy, check)
        if count:
            self._count(stage, value is not None)
        return value

    def put_array(self, stage: str, key: str, arr: np.ndarray) -> None:
        buf = io.BytesIO()
        np.save(buf, np.asarray(arr), allow_pickle=False)
        self.store.write(self.rel(stage, key, "npy"), envelope(buf.getvalue()))

    def put_bytes(self, stage: str, key: str, ext: str, data: bytes) -> None:
        """A file as is, without the checksum envelope (PNG images that are opened by path)."""
        self.store.write(self.rel(stage, key, ext), data)

    def load_json(self, stage: str, key: str, check: Check | None = None):
        """Read an entry regardless of ``force`` and without counting (results of this run)."""
        return self._read(stage, key, "json", _decode_json, check)

    def load_array(self, stage: str, key: str, check: Check | None = None) -> np.ndarray | None:
        return self._read(stage, key, "npy", _decode_npy, check)

    def has(self, stage: str, key: str, ext: str) -> bool:
        return self.store.exists(self.rel(stage, key, ext))

    def counts(self) -> dict[str, dict[str, int]]:
        stages = sorted(set(self.hits) | set(self.misses))
        return {s: {"hits": self.hits[s], "misses": self.misses[s]} for s in stages}


def _decode_json(payload: bytes):
    return json.loads(payload)


def _decode_npy(payload: bytes) -> np.ndarray:
    return np.load(io.BytesIO(payload), allow_pickle=False)
