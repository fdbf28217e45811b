"""Stage cache: content keys, atomic writes, memoised file digests, hit/miss accounting."""

from __future__ import annotations

import hashlib
import importlib
import os
import sys

import numpy as np
import pytest

from harness.core.errors import InputError
from harness.io.files import atomic_write_with
from harness.run.cache import (
    FileDigests,
    StageCache,
    canonical_json,
    digest_json,
    digest_mask,
)
from harness.run.cache.versions import code_digest


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
    warnings = []
    c = StageCache(tmp_path, warn=warnings.append)
    p = c.path("metrics", "bad", "json")
    p.parent.mkdir(parents=True)
    p.write_text("{not json")
    assert c.get_json("metrics", "bad") is None
    assert not p.exists() and len(warnings) == 1 and "discarded" in warnings[0]


@pytest.mark.parametrize("kind", ["json", "npy"])
def test_every_flipped_byte_or_truncation_is_discarded_with_one_warning(tmp_path, kind):
    warnings = []
    c = StageCache(tmp_path, warn=warnings.append)
    if kind == "json":
        c.put_json("metrics", "k", {"psnr": 30.5, "ssim": 0.9})
    else:
        c.put_array("score", "k", np.arange(50, dtype=np.float64))
    stage = "metrics" if kind == "json" else "score"
    p = c.path(stage, "k", kind)
    good = p.read_bytes()
    get = (lambda: c.get_json(stage, "k")) if kind == "json" else (lambda: c.get_array(stage, "k"))
    for pos in range(0, len(good), max(1, len(good) // 40)):
        bad = bytearray(good)
        bad[pos] ^= 0x01
        p.write_bytes(bytes(bad))
        assert get() is None and not p.exists(), pos
    for cut in (0, 10, len(good) // 2, len(good) - 1):
        p.write_bytes(good[:cut])
        assert get() is None and not p.exists(), cut
    p.write_bytes(good)
    assert get() is not None
    assert len(warnings) == len(c.discarded) > 40


def test_schema_check_discards_a_well_formed_wrong_entry(tmp_path):
    from harness.run.verify import metrics_check, prune_check, score_array_check

    warnings = []
    c = StageCache(tmp_path, warn=warnings.append)
    c.put_array("score", "s", np.zeros(10))
    assert c.get_array("score", "s", check=score_array_check(5000)) is None  # 10 scores, 5,000 splats
    c.put_json("prune", "p", {"mask": "0" * 64, "splats_out": 5734, "tau": 0.1, "tau_quantile": 0.3,
                              "seconds": 0.1})
    assert c.get_json("prune", "p", check=prune_check(5000, 0.3)) is None  # more out than in
    c.put_json("metrics", "m", {"psnr": float("nan"), "render_s": 0.1, "metrics_s": 0.1})
    assert c.get_json("metrics", "m", check=metrics_check(["psnr"])) is None
    c.put_json("metrics", "m", {"psnr": float("inf"), "render_s": 0.1, "metrics_s": 0.1})
    assert c.get_json("metrics", "m", check=metrics_check(["psnr"])) is not None  # identical renders
    assert len(warnings) == 3


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.parquet"

    def failing(p):
        p.write_bytes(b"partial")
        raise OSError("disk full")

    with pytest.raises(InputError, match="out.parquet: cannot write: disk full"):  # the path given, not the temp
        atomic_write_with(target, failing)
    assert list(tmp_path.iterdir()) == []
    atomic_write_with(target, lambda p: p.write_bytes(b"done"))
    assert target.read_bytes() == b"done" and len(list(tmp_path.iterdir())) == 1


def test_file_digest_is_content_hashed_every_run(tmp_path):
    f = tmp_path / "scene.ply"
    f.write_bytes(b"x" * 1000)
    d = FileDigests()
    h1 = d.digest(f)
    assert h1 == hashlib.sha256(b"x" * 1000).hexdigest() and d.hashed_bytes == 1000
    assert d.digest(f) == h1 and d.hashed_bytes == 1000  # same identity in one process: read once
    d2 = FileDigests()  # a new process (run) reads the content again: nothing trusted on disk
    assert d2.digest(f) == h1 and d2.hashed_bytes == 1000
    f.write_bytes(b"y" * 1001)
    assert d2.digest(f) != h1 and d2.hashed_bytes == 2001
    folder = tmp_path / "sog"
    folder.mkdir()
    (folder / "meta.json").write_text("{}")
    h_dir = d2.digest(folder)
    (folder / "extra.webp").write_bytes(b"1")
    assert d2.digest(folder) != h_dir


def test_in_place_edit_with_restored_size_and_mtime_changes_the_digest(tmp_path):
    f = tmp_path / "scene.ply"
    f.write_bytes(b"a" * 4096)
    h1 = FileDigests().digest(f)
    st = f.stat()
    with open(f, "r+b") as fh:  # same size, one byte changed, mtime put back
        fh.seek(100)
        fh.write(b"b")
    os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert f.stat().st_size == st.st_size and f.stat().st_mtime_ns == st.st_mtime_ns
    assert FileDigests().digest(f) != h1


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


# ----------------------------------------------------------------------------- issue 24: entries bound to keys
def _png_bytes(seed: int = 0) -> bytes:
    from harness.run.tasks import png_bytes

    return png_bytes(np.random.default_rng(seed).random((12, 16, 3)).astype(np.float32))


def test_an_entry_copied_under_another_key_is_refused(tmp_path):
    """The checksum covers stage/key/ext: a valid entry moved to another name no longer verifies."""
    import shutil

    warnings = []
    c = StageCache(tmp_path, warn=warnings.append)
    c.put_json("metrics", "random", {"psnr": 33.36})
    c.put_json("metrics", "opacity", {"psnr": 56.44})
    shutil.copyfile(c.path("metrics", "random", "json"), c.path("metrics", "opacity", "json"))
    assert c.get_json("metrics", "opacity") is None and c.get_json("metrics", "random") == {"psnr": 33.36}
    assert len(warnings) == 1 and "copied from another key" in warnings[0]
    c.put_array("score", "a", np.arange(4.0))  # the same across stages and extensions
    c.path("render_ref", "a", "npy").parent.mkdir(parents=True)
    shutil.copyfile(c.path("score", "a", "npy"), c.path("render_ref", "a", "npy"))
    assert c.get_array("render_ref", "a") is None


def test_images_are_sealed_and_verified_like_json_entries(tmp_path):
    """Swapped, truncated or edited images are discarded (and so recomputed); a good one is a plain PNG."""
    from PIL import Image

    warnings = []
    c = StageCache(tmp_path, warn=warnings.append)
    c.put_bytes("images", "a", "png", _png_bytes(0))
    c.put_bytes("images", "b", "png", _png_bytes(1))
    pa, pb = c.path("images", "a", "png"), c.path("images", "b", "png")
    with Image.open(pa) as im:  # viewers ignore the private chunk
        assert im.size == (16, 12)
    good_a, good_b = pa.read_bytes(), pb.read_bytes()
    pa.write_bytes(good_b)  # swapped
    pb.write_bytes(good_a)
    assert not c.has("images", "a", "png") and not c.has("images", "b", "png")
    assert not pa.exists() and not pb.exists()
    for bad in (good_a[: len(good_a) // 2], good_a[:-1], good_a[:40] + bytes([good_a[40] ^ 1]) + good_a[41:], b""):
        pa.write_bytes(bad)
        assert not c.path("images", "a", "png").exists()  # path() verifies: a bad image is never handed out
    pa.write_bytes(good_a)
    assert c.has("images", "a", "png") and c.path("images", "a", "png") == pa
    with pytest.raises(ValueError):
        c.put_bytes("images", "x", "jpg", b"...")
    assert len(warnings) == 6


@pytest.mark.parametrize("kind", ["fifo", "devzero", "folder", "symlink-to-entry"])
def test_entries_that_are_not_regular_files_are_refused_without_blocking(tmp_path, kind):
    warnings = []
    c = StageCache(tmp_path, warn=warnings.append)
    c.put_json("metrics", "other", {"psnr": 1.0})
    p = c.path("metrics", "k", "json")
    p.parent.mkdir(parents=True, exist_ok=True)
    if kind == "fifo":
        os.mkfifo(p)
    elif kind == "devzero":
        p.symlink_to("/dev/zero")
    elif kind == "folder":
        p.mkdir()
    else:  # a symlink to a valid entry is not an entry either
        p.symlink_to(c.path("metrics", "other", "json"))
    assert c.get_json("metrics", "k") is None
    assert len(warnings) == 1 and "discarded" in warnings[0]
    assert not os.path.lexists(p)  # the name is gone (never its target): the next run writes a real entry
    assert c.get_json("metrics", "other") == {"psnr": 1.0}
    c.put_json("metrics", "k", {"psnr": 2.0})
    assert c.get_json("metrics", "k") == {"psnr": 2.0}


def test_keyed_caches_refuse_entries_sealed_without_the_key(tmp_path, monkeypatch):
    """HARNESS_CACHE_KEY: an HMAC nobody without the secret can recompute; other entries are recomputed."""
    from harness.run.cache.entries import Sealer

    plain = StageCache(tmp_path, secret=b"")
    plain.put_json("metrics", "k", {"psnr": 30.0})
    monkeypatch.setenv("HARNESS_CACHE_KEY", "s3cret")
    warnings = []
    keyed = StageCache(tmp_path, warn=warnings.append)
    assert keyed.get_json("metrics", "k") is None and "not sealed with this cache's key" in warnings[0]
    keyed.put_json("metrics", "k", {"psnr": 31.0})
    assert keyed.get_json("metrics", "k") == {"psnr": 31.0}
    rel = keyed.rel("metrics", "k", "json")
    forged = Sealer(b"guess").envelope(rel, b'{"psnr": 99.0}')  # a plausible value, sealed with a wrong key
    keyed.path("metrics", "k", "json").write_bytes(forged)
    assert keyed.get_json("metrics", "k") is None and "checksum mismatch" in warnings[1]
    keyed.put_json("metrics", "k", {"psnr": 31.0})
    monkeypatch.delenv("HARNESS_CACHE_KEY")
    assert StageCache(tmp_path, warn=warnings.append).get_json("metrics", "k") is None
    assert "HARNESS_CACHE_KEY is not set" in warnings[2]


def test_audit_lists_every_entry_and_its_problem(tmp_path):
    c = StageCache(tmp_path)
    c.put_json("metrics", "a", {"psnr": 1.0})
    c.put_bytes("images", "a", "png", _png_bytes())
    c.put_array("score", "a", np.zeros(3))
    c.path("metrics", "a", "json").write_bytes(c.path("metrics", "a", "json").read_bytes()[:-1])
    audit = c.audit()
    assert sorted(audit) == ["images/a/a.png", "metrics/a/a.json", "score/a/a.npy"]
    assert (
        audit["images/a/a.png"] is None and audit["score/a/a.npy"] is None and "checksum" in audit["metrics/a/a.json"]
    )
    assert c.path("metrics", "a", "json").exists()  # an audit deletes nothing


def test_a_sog_scene_named_by_its_meta_json_is_keyed_on_every_file_it_reads(tmp_path):
    from tests.test_sog_io import SogSpec

    SogSpec(20, seed=3).write(tmp_path / "s")
    meta = tmp_path / "s" / "meta.json"
    d = FileDigests()
    before = d.scene(meta)
    assert d.scene(tmp_path / "s") == before  # the folder and its meta.json: one scene, one key
    tex = tmp_path / "s" / "quats.webp"
    tex.write_bytes(tex.read_bytes() + b"\0")
    assert FileDigests().scene(meta) != before


def test_process_local_stores_are_refused_for_other_processes(tmp_path, monkeypatch):
    from harness.run.config.executor import ExecutorSpec
    from harness.run.executors import preflight

    monkeypatch.setenv("HARNESS_CACHE", str(tmp_path))
    preflight(ExecutorSpec(), 1, "memory://one/process")  # in-process: fine
    for spec, workers in ((ExecutorSpec(), 2), (ExecutorSpec(name="ray"), 1)):
        with pytest.raises(InputError, match="lives in this process's memory"):
            preflight(spec, workers, "memory://one/process")
    with pytest.raises(InputError, match="Protocol not known"):
        preflight(ExecutorSpec(), 1, "nosuchproto://x")


def test_outputs_honour_the_umask_new_or_replaced(tmp_path):
    old = os.umask(0o027)
    try:
        p = tmp_path / "o.json"
        p.write_text("old")
        os.chmod(p, 0o600)
        atomic_write_with(p, lambda t: t.write_text("new"))
        assert p.stat().st_mode & 0o777 == 0o640
        os.umask(0o022)
        c = StageCache(tmp_path / "c")
        c.put_json("metrics", "k", {"psnr": 1.0})
        assert c.path("metrics", "k", "json").stat().st_mode & 0o777 == 0o644
    finally:
        os.umask(old)
