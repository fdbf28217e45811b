"""Issue 15's hostile-user cases: every one run through the real CLI in a subprocess, classified.

    python -m tests.stress.cases [--root TREE] [--only ID,ID] [--json OUT.json]

``--root`` is the source tree put on PYTHONPATH for the child (default: this checkout), so the
"before" column is measured by pointing it at an export of the starting commit. Each case makes
its own files in a fresh temporary folder (with *this* checkout's writers) and runs one ``harness``
command there, with a wall-clock limit (a hang) and an address-space limit (a bomb).

Outcomes:

* ``clean``: exit 2, exactly one stderr line ``harness: ...``, no traceback, and the case's checks
  (inputs unchanged, nothing written, no temporary files left) hold;
* ``ok``: for the cases where the right answer is success (exit 0 and the checks hold, e.g. valid
  JSON on stdout);
* ``scene error``: for a run where one scene must fail and the rest finish (exit 1, results written);
* otherwise what happened: ``hang``, ``traceback``, ``memory``, ``accepted (exit 0)``,
  ``input changed``, ``wrote output``, ``tmp left``, ``names a temp file``, a failed extra check
  (``mode 600 (want 644)`` ...), ``exit N`` ...; ``skipped: why`` where a case cannot be set up on
  this machine (``mount --bind`` without the right to mount).

Issue 15's families are below; issue 24's (aliases of inputs, cache locations, bounded reads,
limits, one-line failures, named scenes, escaping) are in :mod:`tests.stress.cases_issue24`; bounded
memory (M) in :mod:`tests.stress.cases_memory`, plugins (P) in :mod:`tests.stress.cases_plugins`,
finite numbers and the Python API (F, Y) in :mod:`tests.stress.cases_numbers`, the output folder,
names and checks before the first write (O, U, W) in :mod:`tests.stress.cases_outputs`.

Each case says which outcome it must have (``want``); :func:`run_case` is also what
``tests/stress/test_stress_cases.py`` runs, one test per case.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable
TIMEOUT_S = 40
MEM_LIMIT = 6 << 30


@dataclass
class Setup:
    argv: list[str]
    unchanged: list[Path] = field(default_factory=list)  # input files whose bytes must not change
    absent: list[Path] = field(default_factory=list)     # outputs that must not be written
    strict_json: bool = False                            # stdout must be strict JSON (no NaN/Infinity)
    fsize: int | None = None                             # RLIMIT_FSIZE: a "full disk"
    stdin_devnull: bool = True
    env: dict = field(default_factory=dict)              # environment overrides (e.g. a private HARNESS_CACHE)
    mem_limit: int | None = None                         # RLIMIT_AS other than MEM_LIMIT
    check: Callable[[], "str | None"] | None = None      # an extra check after the run: a problem or None
    cleanup: list = field(default_factory=list)          # callables run after the case (umount ...)
    umask: int | None = None                             # the child's umask
    timeout: float = TIMEOUT_S                           # wall-clock limit (a hang past it)
    skip: str | None = None                              # the case cannot be set up here (why)
    python: str | None = None                            # run this Python code instead of `harness ARGV`
    stderr_has: str | None = None                        # stderr must say this (a warning, the wording)
    stderr_lacks: str | None = None                      # ... and must not say this
    path: list[Path] = field(default_factory=list)       # folders on PYTHONPATH after the tree (installed plugins)
    output_check: Callable[[str, str], "str | None"] | None = None  # a check of (stdout, stderr): a problem or None


@dataclass
class Case:
    id: str
    group: str
    what: str
    setup: Callable[[Path], Setup]
    want: str = "clean"   # or "ok", or "scene error" (exit 1: one scene failed, the run finished)
    slow: bool = False     # runs a study (seconds)


CASES: list[Case] = []


def case(id, group, what, want="clean", slow=False):
    def deco(fn):
        CASES.append(Case(id, group, what, fn, want, slow))
        return fn
    return deco


# ----------------------------------------------------------------------------- file makers
def _ply(d: Path, n=300, name="s.ply", seed=1, sh=0) -> Path:
    sys.path.insert(0, str(ROOT))
    from harness.io.ply import write_ply
    from tests.scene_factory import random_scene

    p = d / name
    write_ply(random_scene(n, sh, seed=seed), p)
    return p


def _edit(p: Path, old: bytes, new: bytes) -> Path:
    data = p.read_bytes()
    assert old in data, old
    p.write_bytes(data.replace(old, new, 1))
    return p


def _sog(d: Path, n=20, seed=3, name="0_0") -> Path:
    sys.path.insert(0, str(ROOT))
    from tests.test_sog_io import SogSpec

    SogSpec(n, seed=seed).write(d / name)
    return d / name


def _lod(d: Path, tree: dict, filenames=("0_0/meta.json",), levels=1, n=20) -> Path:
    _sog(d, n=n)
    (d / "lod-meta.json").write_text(json.dumps({"lodLevels": levels, "filenames": list(filenames), "tree": tree}))
    return d


def _ref(file=0, offset=0, count=10) -> dict:
    return {"file": file, "offset": offset, "count": count}


def _png(path: Path, w: int, h: int, ctype: int, depth: int, rows: bytes | None = None) -> Path:
    """A PNG written by hand (any colour type / bit depth; ``rows`` raw scanlines without filters)."""
    channels = {0: 1, 2: 3, 4: 2, 6: 4}[ctype]
    stride = w * channels * depth // 8
    if rows is None:
        rows = bytes(stride * h)
    raw = b"".join(b"\x00" + rows[y * stride:(y + 1) * stride] for y in range(h))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, ctype, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))
    return path


def _cam(**over) -> dict:
    c = {"id": 0, "img_name": "v0", "width": 64, "height": 48, "position": [0.0, 0.0, -4.0],
         "rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "fx": 55.4, "fy": 55.4}
    c.update(over)
    return c


def _cams(d: Path, text: str | None = None, **over) -> Path:
    p = d / "cams.json"
    p.write_text(text if text is not None else json.dumps([_cam(**over)]))
    return p


def _render_cams(d: Path, **kw) -> Setup:
    s = _ply(d, 50)
    c = _cams(d, **kw)
    return Setup(["render", str(s), "--cameras", str(c), "--out", str(d / "o")], unchanged=[s, c], absent=[d / "o"])


def _config(d: Path, text: str | None = None, **over) -> Path:
    _ply(d, 300)
    cfg = {"name": "t", "output": "out", "protocol": {"longest_side": 32, "metrics": ["psnr"], "n_test": 1,
                                                      "n_train": 0},
           "ratios": [0.3], "scenes": [{"name": "s", "source": "s.ply"}], "methods": ["opacity"]}
    cfg.update(over)
    p = d / "c.yaml"
    p.write_text(text if text is not None else json.dumps(cfg))
    return p


def _run(d: Path, *extra, **kw) -> Setup:
    c = _config(d, **kw)
    return Setup(["run", str(c), "--cache", str(d / "cache"), *extra], unchanged=[c, d / "s.ply"])


def _run_dir(d: Path, rows=None, meta=None, name="r") -> Path:
    sys.path.insert(0, str(ROOT))
    from harness.report.results import to_frame, write_results

    r = d / name
    r.mkdir()
    if rows is None:
        rows = [{"run": "t", "scene": "g", "label": "g", "kind": "object-centric", "frame": "", "method": "opacity",
                 "variant": "default", "params": "{}", "ratio": 0.3, "keep": 0.7, "view": f"v{v}", "status": "ok",
                 "reason": "", "psnr": 30.0 + v, "ssim": 0.9, "lpips": 0.1, "splats_in": 100, "splats_out": 70,
                 "score_s": 1.0, "prune_s": 0.01, "render_ref_s": 0.1, "render_s": 0.1, "metrics_s": 0.1,
                 "renderer": "gl", "width": 32, "height": 24} for v in range(2)]
    write_results(to_frame(rows), r)
    (r / "run.json").write_text(json.dumps(meta if meta is not None else
                                           {"name": "t", "commit": "abc", "machine": {"cpus": 2},
                                            "calibration_s": 0.5, "tables": ["comparison"], "plots": []}))
    return r


# ============================================================================ data loss
@case("D1", "data loss", "prune x.ply x.ply --ratio 0.3 (output = input)")
def _(d):
    s = _ply(d)
    return Setup(["prune", str(s), str(s), "--ratio", "0.3"], unchanged=[s])


@case("D1b", "data loss", "prune x.ply ./x.ply via a symlinked folder (output resolves to input)")
def _(d):
    s = _ply(d)
    (d / "link").symlink_to(d)
    return Setup(["prune", str(s), str(d / "link" / "s.ply"), "--ratio", "0.3"], unchanged=[s])


@case("D1c", "data loss", "prune G G.ply --scores G.ply (scores over the input)")
def _(d):
    s = _ply(d)
    return Setup(["prune", str(s), str(d / "out.ply"), "--ratio", "0.3", "--scores", str(s)],
                 unchanged=[s], absent=[d / "out.ply"])


@case("D2", "data loss", "prune G out.ply --scores DIR (a folder)")
def _(d):
    s = _ply(d)
    (d / "dir.npy").mkdir()
    return Setup(["prune", str(s), str(d / "out.ply"), "--ratio", "0.3", "--scores", str(d / "dir.npy")],
                 unchanged=[s], absent=[d / "out.ply"])


@case("D3", "data loss", "prune G out.ply --scores /proc/x.npy (unwritable)")
def _(d):
    s = _ply(d)
    return Setup(["prune", str(s), str(d / "out.ply"), "--ratio", "0.3", "--scores", "/proc/harness_x.npy"],
                 unchanged=[s], absent=[d / "out.ply"])


@case("D4", "data loss", "prune G /proc/out.ply (output under /proc)")
def _(d):
    s = _ply(d)
    return Setup(["prune", str(s), "/proc/harness_out.ply", "--ratio", "0.3"], unchanged=[s])


@case("D5", "data loss", "prune G out.ply with a 300 KB file-size limit (full disk mid-write)")
def _(d):
    s = _ply(d, 20000)
    return Setup(["prune", str(s), str(d / "out.ply"), "--ratio", "0.3", "--method", "opacity"], unchanged=[s],
                 absent=[d / "out.ply"],
                 fsize=300_000)


# ============================================================================ hangs and bombs
def _fifo(p: Path) -> Path:
    os.mkfifo(p)
    return p


@case("H1", "hang", "mkfifo f.ply; harness info f.ply")
def _(d):
    return Setup(["info", str(_fifo(d / "f.ply"))])


@case("H2", "hang", "a SOG image that is a FIFO")
def _(d):
    f = _sog(d)
    (f / "quats.webp").unlink()
    _fifo(f / "quats.webp")
    return Setup(["info", str(f)])


@case("H3", "hang", "a config that is a FIFO (harness run f.yaml)")
def _(d):
    return Setup(["run", str(_fifo(d / "f.yaml")), "--cache", str(d / "cache")])


@case("H4", "hang", "/dev/zero as a .ply (symlink z.ply -> /dev/zero)")
def _(d):
    (d / "z.ply").symlink_to("/dev/zero")
    return Setup(["info", str(d / "z.ply")])


@case("H5", "hang", "/dev/zero as meta.json")
def _(d):
    (d / "meta.json").symlink_to("/dev/zero")
    return Setup(["info", str(d / "meta.json")])


@case("H6", "hang", "/dev/zero as a SOG image")
def _(d):
    f = _sog(d)
    (f / "quats.webp").unlink()
    (f / "quats.webp").symlink_to("/dev/zero")
    return Setup(["info", str(f)])


@case("H7", "hang", "/dev/zero as the config")
def _(d):
    (d / "c.yaml").symlink_to("/dev/zero")
    return Setup(["run", str(d / "c.yaml"), "--cache", str(d / "cache")])


@case("H8", "hang", "a FIFO as the cameras file (render --cameras fifo.json)")
def _(d):
    s = _ply(d, 50)
    return Setup(["render", str(s), "--cameras", str(_fifo(d / "c.json")), "--out", str(d / "o")], absent=[d / "o"])


@case("B1", "bomb", "lod-meta.json: 20,000 references to the same 2,000 rows (40 M splats)")
def _(d):
    tree = {"children": [{"lods": {"0": _ref(0, 0, 2000)}} for _ in range(20000)]}
    _lod(d, tree, n=2000)
    return Setup(["info", str(d)])


@case("B2", "bomb", "228-byte .npy header claiming 10^5 x 10^5 x 3 (compare)")
def _(d):
    p = d / "a.npy"
    with open(p, "wb") as f:
        np.lib.format.write_array_header_1_0(f, {"descr": "<f4", "fortran_order": False,
                                                 "shape": (100000, 100000, 3)})
    return Setup(["compare", str(p), str(p)])


@case("B3", "bomb", "a 12000x12000 PNG of a few KB (compare)")
def _(d):
    p = _png(d / "big.png", 12000, 12000, 0, 8)
    return Setup(["compare", str(p), str(p)])


@case("B4", "bomb", "render --longest-side 20000")
def _(d):
    s = _ply(d, 50)
    return Setup(["render", str(s), "--rig", "orbit", "--longest-side", "20000", "--out", str(d / "o")],
                 absent=[d / "o"])


@case("B5", "bomb", "a camera 200000 px wide (render --cameras)")
def _(d):
    return _render_cams(d, width=200000, height=200000)


@case("B6", "bomb", "YAML billion laughs in a scene label")
def _(d):
    chain = ['&a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, 9):
        chain.append(f"&a{i} [" + ",".join([f"*a{i - 1}"] * 9) + "]")
    text = "name: t\noutput: out\nratios: [0.3]\nmethods: [opacity]\nscenes:\n  - name: s\n    source: s.ply\n" \
           "    label: [" + ", ".join(chain) + "]\n"
    return _run(d, text=text)


@case("B7", "bomb", "a 9 GB sparse file as a .splat (size limit)")
def _(d):
    p = d / "big.splat"
    with open(p, "wb") as f:
        f.truncate(9 << 30)
    return Setup(["info", str(p)])


# ============================================================================ security
@case("S1", "traversal", "SOG image '../outside_means_l.webp' (outside the scene folder)")
def _(d):
    f = _sog(d / "scene")
    shutil.copy(f / "means_l.webp", d / "outside_means_l.webp")
    meta = json.loads((f / "meta.json").read_text())
    meta["means"]["files"][0] = "../../outside_means_l.webp"
    (f / "meta.json").write_text(json.dumps(meta))
    return Setup(["info", str(f)])


@case("S2", "traversal", "SOG image given as an absolute path")
def _(d):
    f = _sog(d / "scene")
    shutil.copy(f / "means_l.webp", d / "abs.webp")
    meta = json.loads((f / "meta.json").read_text())
    meta["means"]["files"][0] = str(d / "abs.webp")
    (f / "meta.json").write_text(json.dumps(meta))
    return Setup(["info", str(f)])


@case("S3", "traversal", "SOG image '../../../../etc/passwd'")
def _(d):
    f = _sog(d / "scene")
    meta = json.loads((f / "meta.json").read_text())
    meta["quats"]["files"][0] = "../../../../../../../../etc/passwd"
    (f / "meta.json").write_text(json.dumps(meta))
    return Setup(["info", str(f)])


@case("S4", "traversal", "lod-meta filenames ['../other/meta.json'] (outside the LOD folder)")
def _(d):
    _sog(d, name="other")
    (d / "lod").mkdir()
    (d / "lod" / "lod-meta.json").write_text(json.dumps(
        {"lodLevels": 1, "filenames": ["../other/meta.json"], "tree": {"lods": {"0": _ref()}}}))
    return Setup(["info", str(d / "lod")])


@case("S5", "traversal", "SOG image that is a symlink to a file outside the folder")
def _(d):
    f = _sog(d / "scene")
    shutil.copy(f / "quats.webp", d / "q.webp")
    (f / "quats.webp").unlink()
    (f / "quats.webp").symlink_to(d / "q.webp")
    return Setup(["info", str(f)])


# ============================================================================ garbage accepted
@case("G1", "garbage", "PLY header count 100 below the data's 300 rows")
def _(d):
    return Setup(["info", str(_edit(_ply(d), b"element vertex 300\n", b"element vertex 100\n"))])


@case("G2", "garbage", "PLY with 10 KB of trailing garbage")
def _(d):
    p = _ply(d)
    p.write_bytes(p.read_bytes() + b"garbage!" * 1280)
    return Setup(["info", str(p)])


@case("G3", "garbage", "PLY 'property int x' over float bytes")
def _(d):
    return Setup(["info", str(_edit(_ply(d), b"property float x\n", b"property int x\n"))])


@case("G4", "garbage", "PLY 'property uint scale_0' (infinite scales)")
def _(d):
    return Setup(["info", str(_edit(_ply(d), b"property float scale_0\n", b"property uint scale_0\n"))])


@case("G5", "garbage", "ascii PLY: uchar property holding 300.7")
def _(d):
    props = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
             "rot_0", "rot_1", "rot_2", "rot_3"]
    head = "ply\nformat ascii 1.0\nelement vertex 2\n" + "".join(f"property float {p}\n" for p in props) \
        + "property uchar red\nend_header\n"
    row = "0 0 0 0.1 0.1 0.1 0 -4 -4 -4 1 0 0 0 "
    p = d / "a.ply"
    p.write_text(head + row + "300.7\n" + row + "12\n")
    return Setup(["info", str(p)])


@case("G6", "garbage", "info --json of a scene with infinite scale stats prints valid JSON", want="ok")
def _(d):
    p = _ply(d, 20)
    data = bytearray(p.read_bytes())
    sys.path.insert(0, str(ROOT))
    from harness.io.ply import read_ply_header

    h = read_ply_header(p)
    names = [n for n, _ in h.element("vertex").properties]
    off = h.data_offset + 4 * names.index("scale_0")
    data[off:off + 4] = struct.pack("<f", 200.0)  # exp(200) overflows float32
    p.write_bytes(bytes(data))
    return Setup(["info", str(p), "--json"], strict_json=True)


@case("G7", "garbage", "SOG lod reference with a negative count")
def _(d):
    _lod(d, {"children": [{"lods": {"0": _ref(0, 5, -3)}}, {"lods": {"0": _ref(0, 0, 2)}}]})
    return Setup(["info", str(d)])


@case("G8", "garbage", "SOG lod references that overlap (duplicate splats)")
def _(d):
    _lod(d, {"children": [{"lods": {"0": _ref(0, 0, 10)}}, {"lods": {"0": _ref(0, 5, 10)}}]})
    return Setup(["info", str(d)])


@case("G9", "garbage", "SOG lod reference with a float offset 2.7")
def _(d):
    _lod(d, {"lods": {"0": _ref(0, 2.7, 5)}})
    return Setup(["info", str(d)])


@case("G10", "garbage", "SOG lodLevels: true")
def _(d):
    _lod(d, {"lods": {"0": _ref()}}, levels=True)
    return Setup(["info", str(d)])


@case("G11", "garbage", "16-bit grey+alpha PNG compared with the same 16-bit grey image")
def _(d):
    rng = np.random.default_rng(0)
    g = rng.integers(0, 65536, size=(16, 16)).astype(">u2")
    la = np.stack([g, np.full_like(g, 65535)], axis=-1)
    a = _png(d / "la16.png", 16, 16, 4, 16, la.tobytes())
    b = _png(d / "g16.png", 16, 16, 0, 16, g.tobytes())
    return Setup(["compare", str(a), str(b)])


@case("G12", "garbage", "config with a duplicate key (ratios: twice)")
def _(d):
    _config(d)
    text = "name: t\noutput: out\nratios: [0.3]\nratios: [0.5]\nscenes: [{name: s, source: s.ply}]\n" \
           "methods: [opacity]\nprotocol: {longest_side: 32, metrics: [psnr], n_test: 1, n_train: 0}\n"
    return _run(d, text=text)


@case("G13", "garbage", "config ratios: [.nan]")
def _(d):
    text = "name: t\noutput: out\nratios: [.nan]\nscenes: [{name: s, source: s.ply}]\nmethods: [opacity]\n"
    return _run(d, text=text)


@case("G14", "garbage", "tracking baseline with tolerance NaN hides a -10 dB regression")
def _(d):
    sys.path.insert(0, str(ROOT))
    from harness.report import tracking
    from harness.report.results import to_frame

    base = _run_dir(d, name="base")
    rows = [dict(r) for r in to_frame([]).to_dict("records")]
    df, meta = tracking.read_run(base)
    summary = tracking.build_summary(df, meta, calibration_s=0.5)
    b = d / "baseline.json"
    b.write_text(json.dumps({"tolerances": {"psnr": float("nan")}, "summary": summary}))
    df2 = df.copy()
    df2["psnr"] = df2["psnr"] - 10.0
    cur = d / "cur"
    cur.mkdir()
    df2.to_parquet(cur / "results.parquet")
    (cur / "run.json").write_text((base / "run.json").read_text())
    del rows
    return Setup(["track", str(cur), "--baseline", str(b), "--no-history"], unchanged=[b])


@case("G15", "garbage", "prune --voxel inf")
def _(d):
    s = _ply(d)
    return Setup(["prune", str(s), str(d / "o.ply"), "--ratio", "0.3", "--voxel", "inf"], absent=[d / "o.ply"])


@case("G16", "garbage", "render --background 5,5,5")
def _(d):
    s = _ply(d, 50)
    return Setup(["render", str(s), "--rig", "orbit", "--longest-side", "32", "--background", "5,5,5",
                  "--out", str(d / "o")], absent=[d / "o"])


@case("G17", "garbage", "camera fx: \"55.4\" (a string)")
def _(d):
    return _render_cams(d, fx="55.4")


@case("G18", "garbage", "camera width: true")
def _(d):
    return _render_cams(d, width=True)


@case("G19", "garbage", "config with an unknown rig")
def _(d):
    text = "name: t\noutput: out\nratios: [0.3]\nscenes: [{name: s, source: s.ply, rig: {a: 1}}]\n" \
           "methods: [opacity]\n"
    return _run(d, text=text)


# ============================================================================ tracebacks
@case("T1", "traceback", "prune --gamma nan")
def _(d):
    s = _ply(d)
    return Setup(["prune", str(s), str(d / "o.ply"), "--ratio", "0.3", "--gamma", "nan"], absent=[d / "o.ply"])


@case("T2", "traceback", "prune --gamma inf")
def _(d):
    s = _ply(d)
    return Setup(["prune", str(s), str(d / "o.ply"), "--ratio", "0.3", "--gamma", "inf"], absent=[d / "o.ply"])


@case("T3", "traceback", "cameras.json rotation \"abc\"")
def _(d):
    return _render_cams(d, rotation="abc")


@case("T4", "traceback", "cameras.json ragged rotation")
def _(d):
    return _render_cams(d, rotation=[[1, 0, 0], [0, 1], [0, 0, 1]])


@case("T5", "traceback", "cameras.json width: 1e400")
def _(d):
    return _render_cams(d, text=json.dumps([_cam()]).replace('"width": 64', '"width": 1e400'))


@case("T6", "traceback", "cameras.json fx: 1e-300")
def _(d):
    return _render_cams(d, fx=1e-300, fy=1e-300)


@case("T7", "traceback", "cameras.json nested 100,000 deep")
def _(d):
    return _render_cams(d, text="[" * 100000 + "]" * 100000)


@case("T8", "traceback", "transforms.json camera_angle_x: 0")
def _(d):
    s = _ply(d, 50)
    t = d / "transforms.json"
    t.write_text(json.dumps({"camera_angle_x": 0, "w": 64, "h": 48, "frames": [
        {"file_path": "a", "transform_matrix": np.eye(4).tolist()}]}))
    return Setup(["render", str(s), "--cameras", str(t), "--out", str(d / "o")], absent=[d / "o"])


@case("T9", "traceback", "transforms.json w: NaN")
def _(d):
    s = _ply(d, 50)
    t = d / "transforms.json"
    t.write_text(json.dumps({"fl_x": 50, "w": float("nan"), "h": 48, "frames": [
        {"file_path": "a", "transform_matrix": np.eye(4).tolist()}]}))
    return Setup(["render", str(s), "--cameras", str(t), "--out", str(d / "o")], absent=[d / "o"])


@case("T10", "traceback", "COLMAP camera width 2^62")
def _(d):
    s = _ply(d, 50)
    m = d / "colmap"
    m.mkdir()
    (m / "cameras.txt").write_text(f"1 PINHOLE {2**62} 48 50 50 32 24\n")
    (m / "images.txt").write_text("1 1 0 0 0 0 0 4 1 a.png\n\n")
    (m / "points3D.txt").write_text("")
    return Setup(["render", str(s), "--cameras", str(m), "--out", str(d / "o")], absent=[d / "o"])


@case("T11", "traceback", "render --out /proc/x (read-only)")
def _(d):
    s = _ply(d, 50)
    return Setup(["render", str(s), "--rig", "orbit", "--longest-side", "32", "--out", "/proc/harness_out"])


@case("T12", "traceback", "render into a full --out (file-size limit)")
def _(d):
    s = _ply(d, 50)
    return Setup(["render", str(s), "--rig", "orbit", "--longest-side", "64", "--out", str(d / "o")], fsize=2000)


@case("T13", "traceback", "render --backend reference --device cuda without a GPU")
def _(d):
    s = _ply(d, 50)
    return Setup(["render", str(s), "--rig", "orbit", "--longest-side", "32", "--backend", "reference",
                  "--device", "cuda", "--out", str(d / "o")], absent=[d / "o"])


@case("T14", "traceback", "compare --device meta")
def _(d):
    a = _png(d / "a.png", 8, 8, 2, 8)
    return Setup(["compare", str(a), str(a), "--device", "meta"])


@case("T15", "traceback", "SOG lod-meta \"lods\": [1, 2]")
def _(d):
    _lod(d, {"lods": [1, 2]})
    return Setup(["info", str(d)])


@case("T16", "traceback", "SOG lod-meta \"filenames\": [5]")
def _(d):
    _lod(d, {"lods": {"0": _ref()}}, filenames=[5])
    return Setup(["info", str(d)])


@case("T17", "traceback", "a config that is not UTF-8")
def _(d):
    return _run_bytes(d, b"name: t\xe9\xff\nscenes: [s]\n")


def _run_bytes(d: Path, data: bytes) -> Setup:
    _config(d)
    (d / "c.yaml").write_bytes(data)
    return Setup(["run", str(d / "c.yaml"), "--cache", str(d / "cache")], unchanged=[d / "c.yaml"])


@case("T18", "traceback", "config output: a file that exists")
def _(d):
    (d / "afile").write_text("x")
    s = _run(d, output="afile")
    s.unchanged.append(d / "afile")
    return s


@case("T19", "traceback", "run --out FILE")
def _(d):
    (d / "afile").write_text("x")
    s = _run(d, "--out", str(d / "afile"))
    s.unchanged.append(d / "afile")
    return s


@case("T20", "traceback", "run --cache FILE")
def _(d):
    c = _config(d)
    (d / "afile").write_text("x")
    return Setup(["run", str(c), "--cache", str(d / "afile"), "--out", str(d / "out")], unchanged=[d / "afile"])


@case("T21", "traceback", "run --out /proc/x")
def _(d):
    return _run(d, "--out", "/proc/harness_out")


@case("T22", "traceback", "run --cache /proc/x")
def _(d):
    c = _config(d)
    return Setup(["run", str(c), "--cache", "/proc/harness_cache", "--out", str(d / "out")])


@case("T23", "traceback", "a full disk during run (file-size limit)", slow=True)
def _(d):
    s = _run(d)
    s.fsize = 3000
    return s


@case("T24", "traceback", "tables on a corrupt results.parquet")
def _(d):
    r = _run_dir(d)
    (r / "results.parquet").write_bytes(b"PAR1" + os.urandom(500) + b"PAR1")
    return Setup(["tables", str(r)])


@case("T25", "traceback", "tables with run.json [1, 2]")
def _(d):
    r = _run_dir(d, meta=[1, 2])
    return Setup(["tables", str(r)])


@case("T26", "traceback", "tables with run.json \"tables\": 5")
def _(d):
    r = _run_dir(d, meta={"tables": 5})
    return Setup(["tables", str(r)])


@case("T27", "traceback", "track with run.json [1, 2]")
def _(d):
    r = _run_dir(d, meta=[1, 2])
    return Setup(["track", str(r), "--baseline", str(d / "b.json"), "--update-baseline", "--no-history"])


def _results_without(d: Path, column: str | None = None, strings: bool = False) -> Path:
    r = _run_dir(d)
    import pandas as pd

    df = pd.read_parquet(r / "results.parquet")
    if column:
        df = df.drop(columns=[column])
    if strings:
        df["psnr"] = df["psnr"].map(lambda v: f"{v:.2f} dB")
    (r / "results.parquet").unlink()
    df.to_parquet(r / "results.parquet")
    return r


@case("T28", "traceback", "track: results without a psnr column")
def _(d):
    return Setup(["track", str(_results_without(d, "psnr")), "--baseline", str(d / "b.json"), "--update-baseline",
                  "--no-history"])


@case("T29", "traceback", "track: results without a status column")
def _(d):
    return Setup(["track", str(_results_without(d, "status")), "--baseline", str(d / "b.json"),
                  "--update-baseline", "--no-history"])


@case("T30", "traceback", "track: PSNR stored as strings")
def _(d):
    return Setup(["track", str(_results_without(d, strings=True)), "--baseline", str(d / "b.json"),
                  "--update-baseline", "--no-history"])


@case("T31", "traceback", "track --history /proc/x (unwritable history)")
def _(d):
    r = _run_dir(d)
    return Setup(["track", str(r), "--baseline", str(d / "b.json"), "--update-baseline", "--history",
                  "/proc/harness_hist"])


@case("T32", "traceback", "track --baseline /proc/x.json --update-baseline (unwritable baseline)")
def _(d):
    r = _run_dir(d)
    return Setup(["track", str(r), "--baseline", "/proc/harness_b.json", "--update-baseline", "--no-history"])


@case("T33", "traceback", "prune --method lightgs --device cuda without a GPU")
def _(d):
    s = _ply(d, 200)
    c = _cams(d)
    return Setup(["prune", str(s), str(d / "o.ply"), "--ratio", "0.3", "--method", "lightgs", "--cameras", str(c),
                  "--device", "cuda"], absent=[d / "o.ply"])


@case("T34", "traceback", "run with protocol.device: cuda without a GPU", slow=True)
def _(d):
    return _run(d, protocol={"longest_side": 32, "metrics": ["psnr", "ssim"], "n_test": 1, "n_train": 0,
                             "device": "cuda"})


@case("T35", "traceback", "compare a 16-bit RGB PNG with a NaN .npy (one line each way)")
def _(d):
    a = _png(d / "a.png", 4, 4, 2, 16)
    np.save(d / "b.npy", np.full((4, 4, 3), np.nan, np.float32))
    return Setup(["compare", str(a), str(d / "b.npy")])


# ----------------------------------------------------------------------------- running
def _limits(fsize, mem_limit=None, umask=None):
    def apply():
        if umask is not None:
            os.umask(umask)
        resource.setrlimit(resource.RLIMIT_AS, (mem_limit or MEM_LIMIT, mem_limit or MEM_LIMIT))
        if fsize is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))
        os.setsid()
    return apply


def _tmp_files(d: Path) -> list[Path]:
    return [p for p in d.rglob("*") if p.name.endswith(".tmp") and p.name.startswith(".")]


def run_case(c: Case, root: Path = ROOT, work: Path | None = None) -> dict:
    """Set the case up in a fresh folder, run it, classify; returns {id, outcome, rc, stderr, seconds}."""
    import time

    d = Path(tempfile.mkdtemp(prefix=f"case-{c.id}-", dir=work))
    s = None
    try:
        s = c.setup(d)
        if s.skip:
            return {"id": c.id, "group": c.group, "what": c.what, "want": c.want, "outcome": f"skipped: {s.skip}",
                    "rc": None, "stderr": "", "seconds": 0.0}
        before = {p: p.read_bytes() for p in s.unchanged if p.is_file()}
        hcache = d / "hcache"  # a private harness cache; model weights and fetched scenes shared read-only
        hcache.mkdir()
        real = Path(os.environ.get("HARNESS_CACHE", Path.home() / ".cache" / "harness")).expanduser()
        for sub in ("weights", "data"):
            if (real / sub).is_dir():
                (hcache / sub).symlink_to(real / sub)
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(map(str, [root, *s.path])), "HARNESS_CACHE": str(hcache),
               "PYTHONWARNINGS": "ignore", **s.env}
        t0 = time.perf_counter()
        command = [PY, "-c", s.python] if s.python is not None else [PY, "-m", "harness", *s.argv]
        proc = subprocess.Popen(command, cwd=d, env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, stdin=subprocess.DEVNULL,
                                preexec_fn=_limits(s.fsize, s.mem_limit, s.umask))
        try:
            out, err = proc.communicate(timeout=s.timeout)
            rc = proc.returncode
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            out, err = proc.communicate()
            rc = None
        seconds = time.perf_counter() - t0
        out, err = out.decode(errors="replace"), err.decode(errors="replace")
        outcome = classify(c, s, rc, out, err, before, d)
        return {"id": c.id, "group": c.group, "what": c.what, "want": c.want, "outcome": outcome, "rc": rc,
                "stderr": err.strip().splitlines()[-1][:300] if err.strip() else "", "seconds": round(seconds, 2)}
    finally:
        for undo in (s.cleanup if s is not None else []):
            undo()
        shutil.rmtree(d, ignore_errors=True)


def classify(c: Case, s: Setup, rc, out: str, err: str, before: dict, d: Path) -> str:
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    if rc is None:
        return "hang"
    if "MemoryError" in err or rc in (-9, 137):
        return "memory"
    if "Traceback" in err:
        return "traceback"
    if rc < 0:
        return f"signal {-rc}"
    for p, data in before.items():
        if not p.is_file() or p.read_bytes() != data:
            return "input changed"
    wrote = [p for p in s.absent if p.exists()]
    if _tmp_files(d):
        return "tmp left"
    problem = (s.check() if s.check is not None else None) or (s.output_check(out, err) if s.output_check else None)
    if problem:
        return problem
    if s.stderr_has is not None and s.stderr_has not in err:
        return f"stderr lacks {s.stderr_has!r}"
    if s.stderr_lacks is not None and s.stderr_lacks in err:
        return f"stderr says {s.stderr_lacks!r}"
    if c.want == "scene error":  # one scene failed: the run finished, wrote its results and exits 1
        return "scene error" if rc == 1 and (d / "out" / "results.parquet").exists() else \
            f"exit {rc}: {lines[-1][:80] if lines else ''}"
    if c.want == "ok":
        if rc != 0:
            return f"exit {rc}: {lines[-1][:80] if lines else ''}"
        if s.strict_json:
            try:
                json.loads(out, parse_constant=lambda name: (_ for _ in ()).throw(ValueError(name)))
            except ValueError as e:
                return f"invalid JSON ({str(e)[:40]})"
        return "ok"
    if rc == 0:
        return "accepted (exit 0)" + (" + wrote output" if wrote else "")
    if wrote:
        return f"exit {rc} + wrote output"
    # `harness run` prints its progress on stderr before a failure: the error is then its last line
    # and the only `harness: ` line
    errors = [ln for ln in lines if ln.startswith("harness: ")]
    progress_ok = s.argv[:1] == ["run"] and len(errors) == 1 and lines[-1] == errors[0]
    if rc == 2 and ((len(lines) == 1 and lines[0].startswith("harness: ")) or progress_ok):
        import re

        return "names a temp file" if re.search(r"/\.[^/\s]+\.tmp\b", lines[-1]) else "clean"
    return f"exit {rc}, {len(lines)} stderr lines"


def table(before: list[dict], after: list[dict]) -> str:
    """Markdown case table: case -> before -> after (later entries of ``before`` override earlier)."""
    import re

    def short(text: str) -> str:  # the per-case temporary folder says nothing
        return re.sub(r"/tmp/(pytest-of-\w+/pytest-\d+/)?case-[\w-]+?-[a-z0-9_]{8}/", "", text).replace("|", "/")

    b = {r["id"]: {**r, "stderr": short(r.get("stderr", ""))} for r in before}
    after = [{**r, "stderr": short(r.get("stderr", ""))} for r in after]
    rows = ["| case | what | before | after |", "|---|---|---|---|"]
    for r in after:
        was = b.get(r["id"], {}).get("outcome", "(not run)")
        if was == "clean" and b[r["id"]].get("stderr"):
            was = "clean: " + b[r["id"]]["stderr"].split(": ", 2)[-1][:60]
        now = r["outcome"] + (": " + r["stderr"].split(": ", 2)[-1][:90] if r["outcome"] == "clean" else "")
        rows.append(f"| {r['id']} | {r['what']} | {was} | {now} |".replace("\n", " "))
    return "\n".join(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--table", nargs="+", metavar="JSON", default=None,
                    help="print the markdown table of BEFORE.json [BEFORE2.json ...] AFTER.json and exit")
    ap.add_argument("--root", default=str(ROOT))
    ap.add_argument("--only", default=None)
    ap.add_argument("--json", default=None)
    ap.add_argument("--skip-slow", action="store_true")
    args = ap.parse_args(argv)
    if args.table:
        *befores, after = [json.loads(Path(p).read_text()) for p in args.table]
        print(table([r for b in befores for r in b], after))
        return 0
    from tests.stress import cases as registry  # the module the case families add to (not __main__)

    only = set(args.only.split(",")) if args.only else None
    results = []
    for c in registry.CASES:
        if (only and c.id not in only) or (args.skip_slow and c.slow):
            continue
        r = run_case(c, Path(args.root))
        results.append(r)
        print(f"{r['id']:5s} {r['outcome']:28s} {r['seconds']:6.1f}s  {r['what']}  | {r['stderr'][:120]}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    skipped = sum(r["outcome"].startswith("skipped") for r in results)
    good = sum(r["outcome"] == r["want"] for r in results)
    print(f"{good} of {len(results) - skipped} cases as wanted" + (f" ({skipped} skipped)" if skipped else ""))
    return 0 if good == len(results) - skipped else 1


# the families of issue 24, family M and the plugins' (they register into CASES above)
from tests.stress import cases_issue24, cases_memory, cases_numbers, cases_outputs, cases_plugins  # noqa: E402,F401,I001

if __name__ == "__main__":
    sys.exit(main())
