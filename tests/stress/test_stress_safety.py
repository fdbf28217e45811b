"""Issue 15's classes in the fuzz suite: special files, path traversal, decompression bombs, cache
corruption, and kill -9 during a write and during a run.

Every generated case must end cleanly: bad input is one ``harness: ...`` line with exit status 2
(never a hang, a traceback or an allocation sized by a header), a damaged cache entry is never
returned (None, or exactly the value written), a killed writer never leaves a partial destination
and its temporary file is swept by the next writer, and a killed ``harness run`` leaves no worker.
CI budgets are small; ``HARNESS_STRESS=full`` multiplies them (tests/stress/budget.py).
"""

from __future__ import annotations

import io
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from harness.cli import main
from harness.io.ply import write_ply
from tests.scene_factory import random_scene
from tests.stress.budget import n
from tests.stress.cases import _sog

pytestmark = [pytest.mark.stress]
ROOT = Path(__file__).resolve().parents[2]


def _clean(capsys, argv) -> str:
    """Run the CLI in-process; assert one clean line and exit 2; return the line."""
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and lines[0].startswith("harness: ") and "Traceback" not in err, (argv, rc, err)
    return lines[0]


# ----------------------------------------------------------------------------- special files
def _special(kind: str, path: Path) -> Path:
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "devzero":
        path.symlink_to("/dev/zero")
    elif kind == "devnull":
        path.symlink_to("/dev/null")
    elif kind == "folder":
        path.mkdir()
    elif kind == "socket":
        s = socket.socket(socket.AF_UNIX)
        s.bind(str(path))
        s.close()
    elif kind == "dangling":
        path.symlink_to(path.parent / "nowhere")
    return path


SPECIAL = ("fifo", "devzero", "devnull", "folder", "socket", "dangling")
READERS = {
    "ply": lambda p, d: ["info", p],
    "splat": lambda p, d: ["info", p],
    "meta.json": lambda p, d: ["info", p],
    "cameras.json": lambda p, d: ["render", _scene(d), "--cameras", p, "--out", d / "o"],
    "config.yaml": lambda p, d: ["run", p, "--cache", d / "c"],
    "image.png": lambda p, d: ["compare", p, p],
    "image.npy": lambda p, d: ["compare", p, p],
}


def _scene(d: Path) -> Path:
    p = d / "scene.ply"
    if not p.exists():
        write_ply(random_scene(30, 0, seed=1), p)
    return p


@pytest.mark.parametrize("kind", SPECIAL)
@pytest.mark.parametrize("reader", sorted(READERS))
def test_special_files_are_refused(tmp_path, capsys, kind, reader, stress_counts):
    suffix = reader if "." in reader else f"x.{reader}"
    target = _special(kind, tmp_path / suffix)
    line = _clean(capsys, READERS[reader](target, tmp_path))
    assert str(target.name) in line
    assert not (tmp_path / "o").exists()
    stress_counts.add("special files", refused=1)


def test_sog_image_special_files(tmp_path, capsys, stress_counts):
    for kind in SPECIAL:
        f = _sog(tmp_path / kind)
        (f / "scales.webp").unlink()
        _special(kind, f / "scales.webp")
        _clean(capsys, ["info", f])
        stress_counts.add("special files", refused=1)


# ----------------------------------------------------------------------------- path traversal
def _escaping_names(rng, k: int) -> list[str]:
    parts = ["..", ".", "sub", "0_0", "x", "etc", "passwd", "means_l.webp"]
    out = ["../outside.webp", "/etc/passwd", "//etc/passwd", "../../../../../../etc/passwd", "0_0/../../x.webp",
           "sub/../../outside.webp", "./../outside.webp"]
    while len(out) < k:
        depth = int(rng.integers(1, 8))
        name = "/".join(rng.choice(parts, size=depth))
        if rng.random() < 0.3:
            name = "/" + name
        out.append(name)
    return out[:k]


def _escapes(root: Path, name: str) -> bool:
    if name.startswith("/"):
        return True
    target = (root / name).resolve()
    return target != root.resolve() and root.resolve() not in target.parents


def test_sog_paths_never_leave_the_scene_folder(tmp_path, capsys, stress_counts):
    """Random image names in meta.json: an escaping one is refused with 'outside'/'absolute' and
    never read; a name that stays inside behaves as a normal (possibly missing) file."""
    rng = np.random.default_rng(15)
    base = _sog(tmp_path / "scene")
    (tmp_path / "outside.webp").write_bytes((base / "means_l.webp").read_bytes())
    meta0 = json.loads((base / "meta.json").read_text())
    for name in _escaping_names(rng, n(60, 2000)):
        meta = json.loads(json.dumps(meta0))
        meta["means"]["files"][0] = name
        (base / "meta.json").write_text(json.dumps(meta))
        rc = main(["info", str(base)])
        _, err = capsys.readouterr()
        if _escapes(base, name):
            assert rc == 2 and ("outside the scene folder" in err or "absolute path" in err), (name, err)
            stress_counts.add("path traversal", refused=1)
        else:
            assert rc in (0, 2) and "Traceback" not in err and err.count("\n") <= 1, (name, err)
            stress_counts.add("path traversal", inside=1)
    # a symlink inside the folder that leads out is refused too
    (base / "means_l.webp").unlink()
    (base / "means_l.webp").symlink_to(tmp_path / "outside.webp")
    (base / "meta.json").write_text(json.dumps(meta0))
    assert "outside the scene folder" in _clean(capsys, ["info", base])


def test_lod_filenames_never_leave_the_folder(tmp_path, capsys, stress_counts):
    rng = np.random.default_rng(16)
    _sog(tmp_path / "lod", name="0_0")
    _sog(tmp_path, name="other")
    for name in _escaping_names(rng, n(20, 500)):
        if not name.endswith(".json"):
            name = name.rstrip("/") + "/meta.json"
        (tmp_path / "lod" / "lod-meta.json").write_text(json.dumps(
            {"lodLevels": 1, "filenames": [name], "tree": {"lods": {"0": {"file": 0, "offset": 0, "count": 5}}}}))
        rc = main(["info", str(tmp_path / "lod")])
        _, err = capsys.readouterr()
        if _escapes(tmp_path / "lod", name):
            assert rc == 2 and ("outside" in err or "absolute" in err), (name, err)
        else:
            assert rc in (0, 2) and "Traceback" not in err
        stress_counts.add("path traversal", lod=1)


# ----------------------------------------------------------------------------- decompression bombs
def test_npy_headers_are_checked_before_allocating(tmp_path, capsys, stress_counts):
    rng = np.random.default_rng(17)
    p = tmp_path / "a.npy"
    for _ in range(n(40, 1000)):
        ndim = int(rng.integers(1, 5))
        shape = tuple(int(v) for v in rng.integers(1, 10**6, size=ndim))
        dtype = rng.choice(["<f4", "<f8", "|u1", "<u2"])
        with open(p, "wb") as f:
            np.lib.format.write_array_header_1_0(f, {"descr": str(dtype), "fortran_order": False, "shape": shape})
            f.write(os.urandom(int(rng.integers(0, 4096))))
        _clean(capsys, ["compare", p, p])
        stress_counts.add("decompression bombs", npy=1)


def test_png_dimensions_are_checked_before_decoding(tmp_path, capsys, stress_counts):
    rng = np.random.default_rng(18)
    for i in range(n(8, 100)):
        w, h = int(rng.integers(8193, 30000)), int(rng.integers(1, 30000))
        if rng.random() < 0.5:
            w, h = h, w
        p = tmp_path / f"b{i}.png"
        _png_header_only(p, w, h)
        assert "larger than the maximum" in _clean(capsys, ["compare", p, p])
        stress_counts.add("decompression bombs", png=1)


def _png_header_only(path: Path, w: int, h: int) -> None:
    import struct
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    row = b"\x00" + bytes(w)
    comp = zlib.compressobj(9)
    data = b"".join(comp.compress(row) for _ in range(min(h, 64))) + comp.flush()
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
                     + chunk(b"IDAT", data) + chunk(b"IEND", b""))


def test_ply_counts_must_match_the_file_size(tmp_path, capsys, stress_counts):
    rng = np.random.default_rng(19)
    p = tmp_path / "s.ply"
    write_ply(random_scene(200, 0, seed=2), p)
    good = p.read_bytes()
    for _ in range(n(40, 1000)):
        count = int(rng.choice([rng.integers(0, 200), rng.integers(201, 10**9), 2**40]))
        p.write_bytes(good.replace(b"element vertex 200\n", f"element vertex {count}\n".encode(), 1)
                      + (os.urandom(int(rng.integers(1, 500))) if rng.random() < 0.3 else b""))
        _clean(capsys, ["info", p])
        stress_counts.add("decompression bombs", ply_count=1)


def test_lod_references_cannot_expand_beyond_the_data(tmp_path, capsys, stress_counts):
    rng = np.random.default_rng(20)
    _sog(tmp_path, n=50)
    for _ in range(n(30, 800)):
        k = int(rng.integers(2, 400))
        refs = [{"file": 0, "offset": int(rng.integers(0, 40)), "count": int(rng.integers(1, 50))} for _ in range(k)]
        (tmp_path / "lod-meta.json").write_text(json.dumps(
            {"lodLevels": 1, "filenames": ["0_0/meta.json"], "tree": {"children": [{"lods": {"0": r}} for r in refs]}}))
        rc = main(["info", str(tmp_path), "--json"])
        out, err = capsys.readouterr()
        assert rc in (0, 2) and "Traceback" not in err
        if rc == 0:
            assert json.loads(out)["splats"] <= 50  # never more splats than stored
        stress_counts.add("decompression bombs", lod=1)


def test_yaml_alias_bombs_are_refused(tmp_path, capsys, stress_counts):
    for depth in range(3, n(9, 12)):
        chain = ['&a0 ["x","x","x","x","x","x","x","x","x"]']
        chain += [f"&a{i} [" + ",".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, depth)]
        p = tmp_path / "c.yaml"
        p.write_text("name: t\nscenes: [{name: s, label: [" + ", ".join(chain) + "]}]\nmethods: [opacity]\n")
        line = _clean(capsys, ["run", p, "--cache", tmp_path / "c"])
        assert "aliases" in line or "label" in line
        stress_counts.add("decompression bombs", yaml=1)


# ----------------------------------------------------------------------------- cache corruption
def test_corrupted_cache_entries_are_never_used(tmp_path, stress_counts):
    from harness.run.cache import StageCache
    from harness.run.verify import metrics_check, prune_check, score_array_check

    rng = np.random.default_rng(21)
    warnings = []
    c = StageCache(tmp_path, warn=warnings.append)
    scores = rng.random(5000)
    metric = {"psnr": 31.25, "ssim": 0.93, "lpips": 0.08, "render_s": 0.1, "metrics_s": 0.2}
    prune = {"mask": "a" * 64, "splats_out": 3500, "tau": 0.3, "tau_quantile": 0.3, "seconds": 0.01}
    entries = [("score", "npy", scores, score_array_check(5000)), ("metrics", "json", metric,
                                                                   metrics_check(["psnr", "ssim", "lpips"])),
               ("prune", "json", prune, prune_check(5000, 0.3))]
    used_bad = 0
    for i in range(n(300, 5000)):
        stage, ext, value, check = entries[i % len(entries)]
        key = f"k{i}"
        (c.put_array if ext == "npy" else c.put_json)(stage, key, value)
        p = c.path(stage, key, ext)
        data = bytearray(p.read_bytes())
        how = rng.integers(0, 4)
        if how == 0:  # flip bits
            for pos in rng.integers(0, len(data), size=int(rng.integers(1, 4))):
                data[pos] ^= 1 << int(rng.integers(0, 8))
        elif how == 1:  # truncate
            data = data[: int(rng.integers(0, len(data)))]
        elif how == 2:  # append
            data += os.urandom(int(rng.integers(1, 64)))
        else:  # a well-formed but wrong value, re-signed: the schema check must catch it
            if ext == "npy":
                buf = io.BytesIO()
                np.save(buf, rng.random(int(rng.integers(1, 4999))))
                data = bytearray(c.sealer.envelope(c.rel(stage, key, ext), buf.getvalue()))
            else:
                bad = dict(value)
                if stage == "metrics":  # values outside each metric's range (in-range edits cannot be told)
                    invalid = {"psnr": [np.nan, -1.0, -np.inf], "ssim": [np.nan, 2.0, -3.0, np.inf],
                               "lpips": [np.nan, -1.0, np.inf]}
                    k = str(rng.choice(sorted(invalid)))
                    bad[k] = float(rng.choice(invalid[k]))
                else:
                    bad["splats_out"] = int(rng.choice([3501, 5734, -1, 0]))
                data = bytearray(c.sealer.envelope(c.rel(stage, key, ext), json.dumps(bad).encode()))
        p.write_bytes(bytes(data))
        got = c.get_array(stage, key, check=check) if ext == "npy" else c.get_json(stage, key, check=check)
        if got is not None:
            same = np.array_equal(got, value) if ext == "npy" else got == value
            used_bad += not same
            stress_counts.add("cache corruption", unchanged=1)
        else:
            assert not p.exists()  # discarded
            stress_counts.add("cache corruption", discarded=1)
    assert used_bad == 0


# ----------------------------------------------------------------------------- kill -9
WRITER = """
import sys, time
from harness.io.files import atomic_write_with
def slow(tmp):
    with open(tmp, "wb") as f:
        for i in range(400):
            f.write(bytes([int(sys.argv[2])]) * 65536)
            f.flush()
            time.sleep(0.002)
atomic_write_with(sys.argv[1], slow)
"""


def test_kill_during_a_write_never_leaves_a_partial_file(tmp_path, stress_counts):
    """kill -9 / SIGTERM at random instants of an atomic write of 26 MB over an existing file: the
    destination is always the old or the new content, whole; SIGTERM removes its temporary file
    (through the CLI's handler), kill -9 leaves one that the next sweep removes."""
    from harness.io.files import sweep_stale_temps

    rng = np.random.default_rng(22)
    dest = tmp_path / "out.bin"
    dest.write_bytes(b"\x01" * (400 * 65536))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    prog = "from harness.core.lifecycle import install_signal_handlers; install_signal_handlers()\n" + WRITER
    for i in range(n(6, 60)):
        sig = signal.SIGKILL if i % 2 else signal.SIGTERM
        proc = subprocess.Popen([sys.executable, "-c", prog, str(dest), str(2 + i)], env=env)
        time.sleep(float(rng.uniform(0.3, 1.6)))
        proc.send_signal(sig)
        proc.wait(timeout=30)
        data = dest.read_bytes()
        assert len(data) == 400 * 65536 and len(set(data[::65536])) == 1, "partial destination"
        tmps = list(tmp_path.glob(".*.tmp"))
        if sig == signal.SIGTERM:
            assert tmps == [] or proc.returncode == 0
        sweep_stale_temps(tmp_path)
        assert list(tmp_path.glob(".*.tmp")) == []
        stress_counts.add("kill -9 during write", **{sig.name: 1})


def _descendants(pid: int) -> list[int]:
    from tests.stress.experiments import _children

    return _children(pid)


def test_kill_9_of_a_run_takes_its_workers_with_it(tmp_path, stress_counts):
    """A real `harness run --workers 2`: kill -9 of the driver once both workers run; within a few
    seconds no worker (and no resource tracker) survives; a rerun finishes."""
    from tests.stress.experiments import STUDY, _alive, _cmdline

    scene = tmp_path / "s.ply"
    write_ply(random_scene(3000, 1, seed=3), scene)
    cfg = tmp_path / "study.yaml"
    cfg.write_text(STUDY.replace("RATIOS", "[0.1, 0.2, 0.3, 0.4, 0.5]").replace("SCENE", str(scene))
                   .replace("n_test: 2", "n_test: 6").replace("longest_side: 64", "longest_side: 192"))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    argv = [sys.executable, "-m", "harness", "run", str(cfg), "--workers", "2", "--cache", str(tmp_path / "cache"),
            "--out", str(tmp_path / "out")]
    proc = subprocess.Popen(argv, cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    kids: list[int] = []
    t0 = time.time()
    while time.time() - t0 < 180 and proc.poll() is None:
        kids = _descendants(proc.pid)
        if sum("spawn_main" in _cmdline(k) for k in kids) >= 2:
            break
        time.sleep(0.2)
    assert proc.poll() is None, "the run ended before its pool started"
    time.sleep(1.0)
    kids = sorted(set(kids) | set(_descendants(proc.pid)))
    proc.kill()
    proc.wait(timeout=30)
    deadline = time.time() + 10
    while time.time() < deadline and any(_alive(k) for k in kids):
        time.sleep(0.2)
    survivors = [(_cmdline(k), k) for k in kids if _alive(k)]
    for _, k in survivors:
        os.kill(k, signal.SIGKILL)
    assert survivors == [], survivors
    stress_counts.add("kill -9 during run", workers_reaped=len(kids))
    r = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
