"""Stage cache: content keys, atomic writes, memoised file digests, hit/miss accounting."""

from __future__ import annotations

import hashlib
import importlib
import os
import sys

import numpy as np
import pytest

from harness.io.files import atomic_write_with
from harness.run.cache import (
    FileDigests,
    StageCache,
    canonical_json,
    digest_json,
    digest_mask,
)
from harness.run.versions import code_digest


def test_keys_depend_on_content_not_order():
    a = StageCache.key("score", scene="abc", params={"x": 1, "y": [1, 2]})
    b = StageCache.key("score", params={"y": [1, 2], "x": 1}, scene="abc")
    assert a == b
    assert a != StageCache.key("score", scene="abc", params={"x": 1, "y": [2, 1]})
    assert a != StageCache.key("prune", scene="abc", params={"x": 1, "y": [1, 2]})
    assert canonical_json({"v": np.float32(0.5), "a": np.arange(2)}) == '{"a":[0,1],"v":0.5}'
    assert digest_json({"k": 1}) == hashlib.sha256(b'{"k":1}').hexdigest()


def test_json_and_array_round_trip_with_counts(tmp_path):
    c = StageCache(tmp_path)
    assert c.get_json("metrics", "k1") is None
    c.put_json("metrics", "k1", {"psnr": float("inf"), "ssim": 0.5})
    assert c.get_json("metrics", "k1") == {"psnr": float("inf"), "ssim": 0.5}
    arr = np.random.default_rng(0).random(7)
    c.put_array("score", "k2", arr)
    assert np.array_equal(c.get_array("score", "k2"), arr)
    assert c.counts() == {"metrics": {"hits": 1, "misses": 1}, "score": {"hits": 1, "misses": 0}}
    forced = StageCache(tmp_path, force=True)
    assert forced.get_json("metrics", "k1") is None and forced.load_json("metrics", "k1")["ssim"] == 0.5


def test_corrupt_entry_reads_as_a_miss(tmp_path):
    c = StageCache(tmp_path)
    p = c.path("metrics", "bad", "json")
    p.parent.mkdir(parents=True)
    p.write_text("{not json")
    assert c.get_json("metrics", "bad") is None


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.parquet"

    def failing(p):
        p.write_bytes(b"partial")
        raise OSError("disk full")

    with pytest.raises(OSError):
        atomic_write_with(target, failing)
    assert list(tmp_path.iterdir()) == []
    atomic_write_with(target, lambda p: p.write_bytes(b"done"))
    assert target.read_bytes() == b"done" and len(list(tmp_path.iterdir())) == 1


def test_file_digest_is_memoised_by_size_and_mtime(tmp_path):
    f = tmp_path / "scene.ply"
    f.write_bytes(b"x" * 1000)
    d = FileDigests(tmp_path / "index.json")
    h1 = d.digest(f)
    assert h1 == hashlib.sha256(b"x" * 1000).hexdigest() and d.hashed_bytes == 1000
    d2 = FileDigests(tmp_path / "index.json")  # a new process reads the index
    assert d2.digest(f) == h1 and d2.hashed_bytes == 0
    f.write_bytes(b"y" * 1001)
    assert d2.digest(f) != h1 and d2.hashed_bytes == 1001
    folder = tmp_path / "sog"
    folder.mkdir()
    (folder / "meta.json").write_text("{}")
    h_dir = d2.digest(folder)
    (folder / "extra.webp").write_bytes(b"1")
    assert d2.digest(folder) != h_dir


def test_mask_digest():
    m = np.array([True, False, True])
    assert digest_mask(m) == digest_mask(m.copy())
    assert digest_mask(m) != digest_mask(~m)
    assert digest_mask(np.ones(8, bool)) != digest_mask(np.ones(9, bool))  # packbits pads; length counts


def test_code_digest_follows_source(tmp_path, monkeypatch):
    pkg = tmp_path / "cdpkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "mod.py").write_text("X = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    mod = importlib.import_module("cdpkg.mod")
    whole = code_digest("cdpkg")
    single = code_digest(mod)
    (pkg / "mod.py").write_text("X = 2\n")
    assert code_digest("cdpkg") != whole and code_digest(mod) != single
    sys.modules.pop("cdpkg.mod", None)
    sys.modules.pop("cdpkg", None)


def test_no_temp_files_left_after_puts(tmp_path):
    c = StageCache(tmp_path)
    for i in range(5):
        c.put_json("s", f"k{i}", {"i": i})
    leftovers = [p for p in tmp_path.rglob("*") if p.name.endswith(".tmp")]
    assert leftovers == [] and os.path.exists(c.path("s", "k4", "json"))
