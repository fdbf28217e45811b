"""Issue 24's families of hostile-user cases (registered into :data:`tests.stress.cases.CASES`):

* **A — aliases of inputs**: an output that is an input under another name (hard link, bind mount of
  its folder), a camera file or config written over by the command that read it, outputs' mode;
* **K — cache locations**: ``memory://`` across processes, unknown fsspec protocols, missing backends;
* **R — bounded reads**: huge PLY headers, images of a run folder and of a transforms.json that are
  FIFOs or decompression bombs, a history file that is a FIFO or a symlink;
* **L — sizes where they enter**: header camera size lines, ``score --width``;
* **E — one line for every failure**: control characters in a config, tampered LPIPS weights, an
  unreachable Ray address, a zero-splat scene in a run, out of memory;
* **N — named scenes** edited after they were fetched; **X — escaping** of what tables embed.
"""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np

from tests.stress.cases import ROOT, Setup, _cam, _config, _ply, _png, _run, _run_dir, case


def _real_cache() -> Path:
    return Path(os.environ.get("HARNESS_CACHE", Path.home() / ".cache" / "harness")).expanduser()


def _bomb_png(path: Path, w: int = 20000, h: int = 20000) -> Path:
    """A PNG whose header claims ``w × h`` pixels, with one tiny IDAT (a decompression bomb header)."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b""))
    return path


def _mode_is(path: Path, mode: int):
    def check():
        if not path.exists():
            return f"{path.name} not written"
        got = path.stat().st_mode & 0o777
        return None if got == mode else f"mode {got:o} (want {mode:o})"
    return check


# ============================================================================ A: aliases of inputs
@case("A1", "aliases", "prune s.ply h.ply where h.ply is a hard link of s.ply")
def _(d):
    s = _ply(d)
    os.link(s, d / "h.ply")
    # the rename of an atomic write leaves s.ply's bytes alone; refusing is about identity: h.ply *is* the input
    return Setup(["prune", str(s), str(d / "h.ply"), "--ratio", "0.3", "--method", "opacity"], unchanged=[s])


@case("A2", "aliases", "prune a/s.ply b/s.ply where b is a bind mount of a (same file, another path)")
def _(d):
    (d / "a").mkdir()
    (d / "b").mkdir()
    s = _ply(d / "a")
    try:
        ok = subprocess.run(["mount", "--bind", str(d / "a"), str(d / "b")], capture_output=True).returncode == 0
    except OSError:
        ok = False
    if not ok:
        return Setup([], skip="mount --bind is not allowed here")
    setup = Setup(["prune", str(s), str(d / "b" / "s.ply"), "--ratio", "0.3", "--method", "opacity"], unchanged=[s])
    setup.cleanup.append(lambda: subprocess.run(["umount", str(d / "b")], check=False))
    return setup


@case("A3", "aliases", "render g.ply --cameras v16/cameras.json --out v16 (the camera file read)")
def _(d):
    s = _ply(d, 50)
    (d / "v16").mkdir()
    cams = [_cam(img_name=f"v{i}", position=[4 * np.cos(i), 0.0, 4 * np.sin(i)],
                 rotation=[[-np.sin(i), 0.0, -np.cos(i)], [0.0, 1.0, 0.0], [np.cos(i), 0.0, -np.sin(i)]])
            for i in range(16)]
    (d / "v16" / "cameras.json").write_text(json.dumps(cams))
    return Setup(["render", str(s), "--cameras", str(d / "v16" / "cameras.json"), "--out", str(d / "v16"),
                  "--split", "all"], unchanged=[d / "v16" / "cameras.json"], absent=[d / "v16" / "000_v0.png"])


@case("A4", "aliases", "plan c.yaml --out c.yaml (the config read)")
def _(d):
    c = _config(d)
    return Setup(["plan", str(c), "--out", str(c)], unchanged=[c, d / "s.ply"])


@case("A5", "aliases", "plan c.yaml --out s.ply (a scene it read)")
def _(d):
    c = _config(d)
    return Setup(["plan", str(c), "--out", str(d / "s.ply")], unchanged=[c, d / "s.ply"])


@case("A6", "aliases", "plan c.yaml --out DIR (a folder): the error names DIR, not a temp file")
def _(d):
    c = _config(d)
    (d / "dir.json").mkdir()
    return Setup(["plan", str(c), "--out", str(d / "dir.json")], unchanged=[c])


@case("A7", "aliases", "prune output mode under umask 022 (new file, and replacing a 0600 file)", want="ok")
def _(d):
    s = _ply(d)
    out = d / "o.ply"
    out.write_bytes(b"old")
    os.chmod(out, 0o600)
    return Setup(["prune", str(s), str(out), "--ratio", "0.3", "--method", "opacity"], unchanged=[s],
                 check=_mode_is(out, 0o644), umask=0o022)


# ============================================================================ K: cache locations
def _run_with_cache(d: Path, url: str, *extra, **over) -> Setup:
    """``harness run c.yaml --cache URL ...``; nothing may be created (refused before the output folder)."""
    s = _run(d, *extra, "--out", str(d / "out"), **over)
    s.argv[s.argv.index("--cache") + 1] = url
    s.absent.append(d / "out")
    return s


@case("K1", "cache location", "run --cache memory://x --workers 2 (each worker its own memory)")
def _(d):
    s = _run_with_cache(d, "memory://harness-case/x", "--workers", "2", methods=["opacity", "random"],
                        protocol={"longest_side": 32, "metrics": ["psnr"], "n_test": 2, "n_train": 0})
    s.timeout = 150  # a pool of 2 starts slowly: let the run end to see what it does
    return s


@case("K2", "cache location", "run --cache s3://bucket/x without s3fs")
def _(d):
    return _run_with_cache(d, "s3://harness-no-such-bucket/x")


@case("K3", "cache location", "run --cache foo://x (unknown fsspec protocol)")
def _(d):
    return _run_with_cache(d, "foo://x")


# ============================================================================ R: bounded reads
def _wide_header(d: Path, n: int) -> Path:
    p = _ply(d, 10)
    p.write_bytes(p.read_bytes().replace(b"end_header\n", b"".join(b"property float e%d\n" % i for i in range(n))
                                         + b"end_header\n", 1))
    return p


@case("R1", "bounded reads", "PLY header with 20,000 property lines (info)")
def _(d):
    return Setup(["info", str(_wide_header(d, 20000))])


@case("R2", "bounded reads", "PLY header with 50,000 property lines (info)")
def _(d):
    return Setup(["info", str(_wide_header(d, 50000))])


def _report_dir(d: Path, bad) -> Setup:
    r = _run_dir(d)
    img = r / "images" / "g"
    img.mkdir(parents=True)
    _png(img / "input.png", 32, 24, 2, 8)
    bad(img / "opacity__default__r0.30.png")
    return Setup(["report", str(r)], absent=[r / "report.html"])


@case("R3", "bounded reads", "report: a FIFO among the run's images/")
def _(d):
    return _report_dir(d, os.mkfifo)


@case("R4", "bounded reads", "report: a PNG in images/ whose header claims 20000x20000")
def _(d):
    return _report_dir(d, _bomb_png)


@case("R5", "bounded reads", "transforms.json frame image whose header claims 20000x20000 (no w/h)")
def _(d):
    s = _ply(d, 50)
    _bomb_png(d / "a.png")
    t = d / "transforms.json"
    t.write_text(json.dumps({"camera_angle_x": 0.8, "frames": [{"file_path": "a.png",
                                                                 "transform_matrix": np.eye(4).tolist()}]}))
    return Setup(["render", str(s), "--cameras", str(t), "--out", str(d / "o")], absent=[d / "o"])


def _track(d: Path, history) -> Setup:
    r = _run_dir(d)
    hist = d / "hist"
    hist.mkdir()
    history(hist / "history.jsonl")
    return Setup(["track", str(r), "--baseline", str(d / "b.json"), "--update-baseline", "--history", str(hist)])


@case("R6", "bounded reads", "track: the history file is a FIFO")
def _(d):
    return _track(d, os.mkfifo)


@case("R7", "bounded reads", "track: the history file is a symlink to another file")
def _(d):
    victim = d / "victim.txt"
    victim.write_text("not a history\n")
    s = _track(d, lambda p: p.symlink_to(victim))
    s.unchanged.append(victim)
    return s


# ============================================================================ L: sizes where they enter
@case("L1", "limits", "render with a PLY header camera size line of 12000x12000")
def _(d):
    p = _ply(d, 50)
    head = (b"ply\ncomment camera_position_resolution 12000 12000\n"
            b"comment camera_position 0 0 0 0 -4 1 0 0 0 9000 9000 v0\n")
    p.write_bytes(p.read_bytes().replace(b"ply\n", head, 1))
    return Setup(["render", str(p), "--out", str(d / "o")], unchanged=[p], absent=[d / "o" / "cameras.json"])


@case("L2", "limits", "score s.ply s.ply --width 16384 --height 1080")
def _(d):
    p = _ply(d, 50)
    head = b"ply\ncomment camera_position 0 0 0 0 -4 1 0 0 0 500 500 v0\n"
    p.write_bytes(p.read_bytes().replace(b"ply\n", head, 1))
    return Setup(["score", str(p), str(p), "--width", "16384", "--height", "1080"], unchanged=[p])


# ============================================================================ E: one line for every failure
@case("E1", "one line", "config with a NUL byte")
def _(d):
    s = _run(d)
    (d / "c.yaml").write_bytes(b"name: t\x00\nscenes: [s]\n")
    return s


@case("E2", "one line", "config with a control character (BEL)")
def _(d):
    s = _run(d)
    (d / "c.yaml").write_bytes(b"name: t\x07\nscenes: [s]\n")
    return s


@case("E3", "one line", "tampered LPIPS weights with a matching .sha256 (compare)")
def _(d):
    import hashlib

    real = _real_cache() / "weights"
    if not (real / "lpips_vgg16_v0.1.pt").is_file():
        return Setup([], skip="no LPIPS weights on this machine")
    wc = d / "wcache"
    (wc / "weights").mkdir(parents=True)
    w = wc / "weights" / "lpips_vgg16_v0.1.pt"
    sys.path.insert(0, str(ROOT))
    import argparse

    import torch

    torch.save({"format": 1, "net": argparse.Namespace(x=1)}, w)  # a class weights_only refuses
    (wc / "weights" / "lpips_vgg16_v0.1.pt.sha256").write_text(
        f"{hashlib.sha256(w.read_bytes()).hexdigest()}  {w.name}\n")
    a = _png(d / "a.png", 16, 16, 2, 8)
    return Setup(["compare", str(a), str(a)], env={"HARNESS_CACHE": str(wc)}, unchanged=[w])


@case("E4", "one line", "run --address 127.0.0.1:1 (nothing listening)")
def _(d):
    s = _run(d, "--address", "127.0.0.1:1", "--out", str(d / "out"))
    s.absent.append(d / "out")
    return s


@case("E5", "one line", "run with a zero-splat scene beside a good one: that scene fails, the run finishes",
      want="scene error", slow=True)
def _(d):
    _ply(d, 0, name="e.ply")
    s = _run(d, "--out", str(d / "out"))
    cfg = json.loads((d / "c.yaml").read_text())
    cfg["scenes"].append({"name": "e", "source": "e.ply"})
    (d / "c.yaml").write_text(json.dumps(cfg))
    return s


@case("E6", "one line", "info of a 460 MB scene under a 1 GiB address-space limit (MemoryError)")
def _(d):
    p = _ply(d, 10)
    data = p.read_bytes()
    head, _, _ = data.partition(b"end_header\n")
    n = 8_000_000
    p.write_bytes(head.replace(b"element vertex 10", b"element vertex %d" % n) + b"end_header\n")
    row = (len(data) - len(head) - len(b"end_header\n")) // 10
    with open(p, "r+b") as f:
        f.truncate(f.seek(0, 2) + n * row)
    return Setup(["info", str(p)], mem_limit=1 << 30)


# ============================================================================ N: named scenes
@case("N1", "named scenes", "grape-small edited after it was fetched (info grape-small)")
def _(d):
    real = _real_cache() / "data" / "grape_small.ply"
    mirror = Path(os.environ.get("HARNESS_SHARED_DATA", ROOT.parent / "shared" / "data")) / "grape_small.ply"
    src = real if real.is_file() else mirror
    if not src.is_file():
        return Setup([], skip="grape_small.ply is not on this machine")
    nc = d / "ncache"
    (nc / "data").mkdir(parents=True)
    copy = nc / "data" / "grape_small.ply"
    shutil.copy(src, copy)
    data = bytearray(copy.read_bytes())
    data[-100] ^= 0x40  # an opacity / SH byte of the last splats
    copy.write_bytes(bytes(data))
    return Setup(["info", "grape-small"], env={"HARNESS_CACHE": str(nc), "HARNESS_SHARED_DATA": str(d / "none")},
                 unchanged=[copy])


# ============================================================================ X: escaping
@case("X1", "escaping", "tables: a scene label \\input{/etc/passwd} in the .tex table", want="ok")
def _(d):
    evil = r"\input{/etc/passwd}"
    rows = [{"run": "t", "scene": "g", "label": evil, "kind": "object-centric", "frame": "", "method": m,
             "variant": "default", "params": "{}", "ratio": 0.3, "keep": 0.7, "view": f"v{v}", "status": "ok",
             "reason": "", "psnr": 30.0 + v + (m == "random"), "ssim": 0.9, "lpips": 0.1, "splats_in": 100,
             "splats_out": 70, "score_s": 1.0, "prune_s": 0.01, "render_ref_s": 0.1, "render_s": 0.1,
             "metrics_s": 0.1, "renderer": "gl", "width": 32, "height": 24}
            for m in ("opacity", "random") for v in range(2)]
    r = _run_dir(d, rows=rows)

    def check():
        tex = r / "tables" / "comparison.tex"
        if not tex.exists():
            return "no comparison.tex"
        return "\\input{ embedded verbatim" if evil in tex.read_text() else None
    return Setup(["tables", str(r), "--tables", "comparison"], check=check)
