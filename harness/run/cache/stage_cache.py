"""Content-addressed, verified stage cache: every stage result is stored under the sha256 of its
inputs, with the sha256 of its own bytes, and is checked before it is used.

``key = sha256(canonical JSON of {stage, inputs, format})`` where the inputs name everything the
result depends on: scene file **content** digests (:class:`FileDigests`: every file is hashed on
every run, never trusted by size/mtime), method + resolved params, camera set (:func:`digest_json`
of the camera dicts), renderer / metric / pruner code versions
(:func:`harness.run.cache.versions.code_digest` of their source files). Values live at
``<root>/<stage>/<key[:2]>/<key>.<ext>``.

**Verification.** Every entry is sealed with a checksum bound to its own name
(:mod:`harness.run.cache.entries`: JSON and ``.npy`` payloads in an envelope, PNG images with a
private chunk), so a damaged entry and an entry copied under another key both fail; with
``HARNESS_CACHE_KEY`` set the checksum is an HMAC that cannot be recomputed without the secret. A
read then runs the caller's schema check (:mod:`harness.run.verify`: length = splat count, prune
counts ≤ input, finite metrics ...) on the decoded value. An entry that fails either — or that is
not a regular file at all (a FIFO, a symlink to ``/dev/zero``: :mod:`harness.run.cache.stores`) —
is **discarded**: a one-line warning, the name deleted, and it reads as a miss, so the stage
recomputes it. What this can and cannot detect: docs/safety.md.

**Scene keys** cover every file a scene reads (:meth:`FileDigests.scene`): a SOG scene named by its
``meta.json`` or ``lod-meta.json`` is keyed on its whole folder (its textures and LOD files may
only lie there), so editing one texture changes the key.

**Atomic publish, many writers.** Entries are written to a temporary file in the destination's
folder (name ``.<name>.<host>.<pid>.<random>.tmp``), fsynced and renamed into place
(:mod:`harness.io.files`), so a reader — in this process, another worker, or another node sharing
the folder — sees the old entry, the complete new one, or none. Two writers of one key write the
same content (keys are content addresses of deterministic computations) and the last rename wins;
a reader that races a deletion of a bad entry sees a miss. All storage access goes through a store
(:mod:`harness.run.cache.stores`): a folder (local, or a shared filesystem every node of a cluster
mounts: NFS, CephFS, Lustre — rename is atomic there too), or an fsspec URL (``s3://bucket/prefix``,
``gs://...``), where each entry is published by **one** PUT. ``memory://`` lives inside one process:
it serves a one-worker local run only (:func:`harness.run.executors.preflight` refuses it otherwise).

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

from harness.run.cache.entries import Sealer, cache_secret
from harness.run.cache.stores import BadEntry, FsspecStore, LocalStore, is_url, open_store

__all__ = ["CACHE_FORMAT", "FileDigests", "StageCache", "canonical_json", "digest_bytes", "digest_json",
           "digest_mask", "is_url", "open_store"]

_HASH_CHUNK = 1 << 20
#: part of every key: entries of an older layout (checksums not bound to their key) are never looked up
CACHE_FORMAT = 3


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

    def __init__(self):
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

    def scene(self, path: str | Path) -> str:
        """Digest of everything a scene read depends on (:func:`harness.io.scenes.scene_extent`):
        the file, or the folder of a SOG scene named by one of its JSON files."""
        from harness.io.scenes import scene_extent

        return self.digest(scene_extent(Path(path)))


def _warn_stderr(message: str) -> None:
    print(f"harness: warning: {message}", file=sys.stderr, flush=True)


Check = Callable[[Any], "str | None"]


# --------------------------------------------------------------------------- the cache
class StageCache:
    """Results keyed by content. ``get_*`` return None on a miss (or a discarded bad entry);
    ``put_*`` store atomically. ``check`` arguments are schema checks returning a problem or None."""

    def __init__(self, root: str | Path, force: bool = False, warn: Callable[[str], None] | None = None,
                 store: LocalStore | FsspecStore | None = None, secret: bytes | None = None):
        """``root``: a folder, ``file://FOLDER`` or an fsspec URL (see :func:`open_store`);
        ``secret``: the MAC key of a shared cache (default ``HARNESS_CACHE_KEY``, else none)."""
        opened, self.root = open_store(root)
        #: what a worker is given to open the same cache (an absolute folder, or the URL)
        self.location = str(root) if isinstance(opened, FsspecStore) else str(self.root.absolute())
        self.force = force  # every lookup misses (results are recomputed and overwritten)
        self.root.mkdir(parents=True, exist_ok=True)
        self.store = store or opened
        self.sealer = Sealer(cache_secret() if secret is None else secret)
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
        """Where an entry that other code opens by path is (a PNG image): verified first — a bad
        one is discarded, and the path returned then does not exist."""
        if ext == "png":
            self.has(stage, key, ext)
        return self.store.path(self.rel(stage, key, ext))

    def count(self, stage: str, hit: bool) -> None:
        """Record a hit or a miss of ``stage`` (for an entry judged by more than one read, e.g. a
        score record and its array: the reads say ``count=False`` and the caller counts once)."""
        (self.hits if hit else self.misses)[stage] += 1

    def discard(self, stage: str, key: str, ext: str, problem: str) -> None:
        """Delete a bad entry and say so in one line."""
        self.store.delete(self.rel(stage, key, ext))
        self.discarded.append(f"{stage}/{key[:12]}: {problem}")
        self.warn(f"stage cache {stage} entry {key[:12]}.{ext}: {problem}; discarded, it will be recomputed")

    def _read(self, stage: str, key: str, ext: str, decode, check: Check | None):
        rel = self.rel(stage, key, ext)
        try:
            data = self.store.read(rel)
        except BadEntry as err:
            self.discard(stage, key, ext, str(err))
            return None
        if data is None:
            return None
        payload, problem = (self.sealer.open_png if ext == "png" else self.sealer.open_envelope)(rel, data)
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

    def _write(self, stage: str, key: str, ext: str, payload: bytes) -> None:
        rel = self.rel(stage, key, ext)
        sealed = self.sealer.sign_png(rel, payload) if ext == "png" else self.sealer.envelope(rel, payload)
        self.store.write(rel, sealed)

    # JSON values ------------------------------------------------------------------
    def get_json(self, stage: str, key: str, count: bool = True, check: Check | None = None):
        value = None if self.force else self._read(stage, key, "json", _decode_json, check)
        if count:
            self.count(stage, value is not None)
        return value

    def put_json(self, stage: str, key: str, value) -> None:
        self._write(stage, key, "json", json.dumps(value, allow_nan=True, default=float, sort_keys=True).encode())

    # array values -------------------------------------------------------------------
    def get_array(self, stage: str, key: str, count: bool = True, check: Check | None = None) -> np.ndarray | None:
        value = None if self.force else self._read(stage, key, "npy", _decode_npy, check)
        if count:
            self.count(stage, value is not None)
        return value

    def put_array(self, stage: str, key: str, arr: np.ndarray) -> None:
        buf = io.BytesIO()
        np.save(buf, np.asarray(arr), allow_pickle=False)
        self._write(stage, key, "npy", buf.getvalue())

    def put_bytes(self, stage: str, key: str, ext: str, data: bytes) -> None:
        """A file that other code opens by path: a PNG image, signed in place (module docstring)."""
        if ext != "png":
            raise ValueError(f"put_bytes stores PNG images; got .{ext} (use put_json / put_array)")
        self._write(stage, key, ext, data)

    def load_json(self, stage: str, key: str, check: Check | None = None):
        """Read an entry regardless of ``force`` and without counting (results of this run)."""
        return self._read(stage, key, "json", _decode_json, check)

    def load_array(self, stage: str, key: str, check: Check | None = None) -> np.ndarray | None:
        return self._read(stage, key, "npy", _decode_npy, check)

    def has(self, stage: str, key: str, ext: str) -> bool:
        """Whether a verified entry is there (a bad one is discarded and counts as absent)."""
        return self._read(stage, key, ext, _decode_raw, None) is not None

    def audit(self) -> dict[str, str | None]:
        """{rel: problem or None} of every entry of a folder cache (nothing is deleted): which
        entries a read would accept. Temporary files and probes are not entries."""
        out: dict[str, str | None] = {}
        for p in sorted(self.root.rglob("*.*")):
            rel = str(p.relative_to(self.root))
            ext = p.suffix[1:]
            if p.name.startswith(".") or rel.startswith((".", "mirror/")) or ext not in ("json", "npy", "png"):
                continue
            try:
                data = self.store.read(rel)
            except BadEntry as err:
                out[rel] = str(err)
                continue
            if data is not None:
                out[rel] = (self.sealer.open_png if ext == "png" else self.sealer.open_envelope)(rel, data)[1]
        return out

    def counts(self) -> dict[str, dict[str, int]]:
        stages = sorted(set(self.hits) | set(self.misses))
        return {s: {"hits": self.hits[s], "misses": self.misses[s]} for s in stages}


def _decode_raw(payload: bytes) -> bytes:
    return payload


def _decode_json(payload: bytes):
    return json.loads(payload)


def _decode_npy(payload: bytes) -> np.ndarray:
    return np.load(io.BytesIO(payload), allow_pickle=False)
