"""Content-addressed stage cache: every stage result is stored under the sha256 of its inputs.

``key = sha256(canonical JSON of {stage, inputs})`` where the inputs name everything the result
depends on: scene file digests (:func:`file_digest`), method + resolved params, camera set
(:func:`digest_json` of the camera dicts), renderer / metric / pruner code versions
(:func:`harness.run.versions.code_digest` of their source files). Values live at ``<root>/<stage>/<key[:2]>/<key>.<ext>``.

Writes are atomic (temp file in the same folder + ``os.replace``), so ``kill -9`` at any instant
leaves either the complete entry or none: nothing already stored is ever lost or half-written.
Hit/miss counts per stage are kept so a run can prove that a rerun recomputed nothing.

Big files are hashed once: digests are memoised in ``<root>/filedigests.json`` keyed by
(absolute path, size, mtime_ns), so a rerun does not re-read a 40 MB scene to know it is unchanged.
"""

from __future__ import annotations

import hashlib
import json
import threading
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from harness.io.files import atomic_write_bytes, atomic_write_text

_HASH_CHUNK = 1 << 20


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
    """sha256 of files and folders, memoised on disk by (path, size, mtime_ns)."""

    def __init__(self, index_path: Path | None):
        self.index_path = Path(index_path) if index_path else None
        self._lock = threading.Lock()
        self._memo: dict[str, dict] = {}
        if self.index_path and self.index_path.exists():
            try:
                self._memo = json.loads(self.index_path.read_text())
            except (OSError, ValueError):
                self._memo = {}
        self.hashed_bytes = 0

    def _file(self, path: Path) -> str:
        st = path.stat()
        key = str(path.resolve())
        entry = self._memo.get(key)
        if entry and entry["size"] == st.st_size and entry["mtime_ns"] == st.st_mtime_ns:
            return entry["sha256"]
        h = hashlib.sha256()
        with open(path, "rb") as f:
            while chunk := f.read(_HASH_CHUNK):
                h.update(chunk)
        self.hashed_bytes += st.st_size
        with self._lock:
            self._memo[key] = {"size": st.st_size, "mtime_ns": st.st_mtime_ns, "sha256": h.hexdigest()}
            if self.index_path:
                atomic_write_text(self.index_path, json.dumps(self._memo, indent=0, sort_keys=True))
        return h.hexdigest()

    def digest(self, path: str | Path) -> str:
        """Digest of a file, or of a folder (relative names + file digests, sorted)."""
        path = Path(path)
        if path.is_dir():
            items = sorted(p for p in path.rglob("*") if p.is_file())
            return digest_json([[str(p.relative_to(path)), self._file(p)] for p in items])
        return self._file(path)


# --------------------------------------------------------------------------- the cache
class StageCache:
    """Results keyed by content. ``get_*`` return None on a miss; ``put_*`` store atomically."""

    def __init__(self, root: str | Path, force: bool = False):
        self.root = Path(root)
        self.force = force  # every lookup misses (results are recomputed and overwritten)
        self.root.mkdir(parents=True, exist_ok=True)
        self.files = FileDigests(self.root / "filedigests.json")
        self.hits: Counter = Counter()
        self.misses: Counter = Counter()

    @staticmethod
    def key(stage: str, **inputs) -> str:
        return digest_json({"stage": stage, **inputs})

    def path(self, stage: str, key: str, ext: str) -> Path:
        return self.root / stage / key[:2] / f"{key}.{ext}"

    def _count(self, stage: str, hit: bool) -> None:
        (self.hits if hit else self.misses)[stage] += 1

    # JSON values ------------------------------------------------------------------
    def get_json(self, stage: str, key: str, count: bool = True):
        p = self.path(stage, key, "json")
        try:
            value = None if self.force else json.loads(p.read_text())
        except FileNotFoundError:
            value = None
        except (OSError, ValueError):  # unreadable entry: treat as absent, it will be rewritten
            value = None
        if count:
            self._count(stage, value is not None)
        return value

    def put_json(self, stage: str, key: str, value) -> None:
        atomic_write_text(self.path(stage, key, "json"), json.dumps(value, allow_nan=True, default=float))

    # array values -------------------------------------------------------------------
    def get_array(self, stage: str, key: str, count: bool = True) -> np.ndarray | None:
        p = self.path(stage, key, "npy")
        try:
            value = None if self.force else np.load(p, allow_pickle=False)
        except FileNotFoundError:
            value = None
        except (OSError, ValueError):
            value = None
        if count:
            self._count(stage, value is not None)
        return value

    def put_array(self, stage: str, key: str, arr: np.ndarray) -> None:
        import io

        buf = io.BytesIO()
        np.save(buf, np.asarray(arr), allow_pickle=False)
        atomic_write_bytes(self.path(stage, key, "npy"), buf.getvalue())

    def load_json(self, stage: str, key: str):
        """Read an entry regardless of ``force`` and without counting (results of this run)."""
        try:
            return json.loads(self.path(stage, key, "json").read_text())
        except (OSError, ValueError):
            return None

    def load_array(self, stage: str, key: str) -> np.ndarray | None:
        try:
            return np.load(self.path(stage, key, "npy"), allow_pickle=False)
        except (OSError, ValueError):
            return None

    def has(self, stage: str, key: str, ext: str) -> bool:
        return self.path(stage, key, ext).exists()

    def counts(self) -> dict[str, dict[str, int]]:
        stages = sorted(set(self.hits) | set(self.misses))
        return {s: {"hits": self.hits[s], "misses": self.misses[s]} for s in stages}
