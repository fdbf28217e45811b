"""The cache-corruption experiments (issues 15 and 24), run on real studies through the CLI.

    python -m tests.stress.experiments cache [--root TREE] [--json OUT] [--only C1,C17]

A small study (grape-small, 5,000 splats; opacity + random; 2 ratios; 2 views; PSNR/SSIM/LPIPS at
64 px) is run once cold; then, for each experiment, a copy of that cache is damaged in one way and
the study rerun (some with an added ratio, so cached scores, masks and reference renders are read
to compute new rows). An experiment passes when the rerun exits 0 and its metric rows — and, for
the image experiments, the images it copies into the run folder — equal the clean run's to the bit
(the bad entry was not used: discarded with a warning and recomputed); for an edited scene, when
the results equal those of a cold run on the edited scene. Issue 24 adds: an entry copied under
another key, swapped / truncated images, a FIFO or a symlink to /dev/zero in an entry's place, an
edited texture of a SOG scene named by its meta.json, ``memory://`` with two workers, and a
plausible value re-sealed with a recomputed checksum — without and with ``HARNESS_CACHE_KEY``.

Every rerun has a wall-clock limit (a hang) and a 6 GiB address-space limit (a memory blow-up).
The damage is written independently of the code under test: the checksum layouts are
re-implemented here (``_seal``), so the same script measures the tree before and after.
"""

from __future__ import annotations

import hashlib
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

PY = sys.executable
MEM_LIMIT = 6 << 30
STUDY = """name: exp
output: out
workers: 1
protocol: {longest_side: 64, metrics: [psnr, ssim, lpips], n_train: 0, n_test: 2, seed: 0}
ratios: RATIOS
scenes:
  - {name: g, source: SCENE}
methods: [opacity, random]
tables: [comparison]
plots: []
"""
KEY = "experiment-secret"


def _env(root: Path, extra: dict | None = None) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "HARNESS_CACHE_KEY"}  # keyed only where asked
    return {**env, "PYTHONPATH": str(root), "HARNESS_SHARED_DATA": os.environ.get(
        "HARNESS_SHARED_DATA", "/work/shared/data"), "PYTHONWARNINGS": "ignore", **(extra or {})}


def _limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (MEM_LIMIT, MEM_LIMIT))


def harness(root: Path, cwd: Path, *argv, timeout=300, env=None) -> subprocess.CompletedProcess:
    """Run the CLI; a run past ``timeout`` is killed with its process group (``returncode`` None)."""
    proc = subprocess.Popen([PY, "-m", "harness", *argv], cwd=cwd, env=_env(root, env), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL, start_new_session=True,
                            preexec_fn=_limit_memory)
    try:
        out, err = proc.communicate(timeout=timeout)
        rc = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        rc = None
    return subprocess.CompletedProcess(proc.args, rc, out, err)


def _study(d: Path, scene: Path, ratios="[0.1, 0.3]") -> Path:
    p = d / "study.yaml"
    p.write_text(STUDY.replace("RATIOS", ratios).replace("SCENE", str(scene)))
    return p


def _metrics(run_dir: Path):
    import pandas as pd

    df = pd.read_parquet(run_dir / "results.parquet")
    df = df[df["status"] == "ok"].sort_values(["method", "ratio", "view"])
    return df[["method", "ratio", "view", "psnr", "ssim", "lpips", "splats_in", "splats_out", "width",
               "height"]].reset_index(drop=True)


def _images(run_dir: Path) -> dict:
    """{relative path: decoded pixels} of the images a run copied into its folder."""
    import numpy as np
    from PIL import Image

    out = {}
    for p in sorted((run_dir / "images").rglob("*.png")):
        with Image.open(p) as im:
            out[str(p.relative_to(run_dir))] = np.asarray(im.convert("RGB")).tobytes()
    return out


# ----------------------------------------------------------------------------- entry layouts
_MAGICS = (b"HCE1 ", b"HCE2 ", b"HCM2 ")


def _entries(cache: Path, stage: str, ext: str) -> list[Path]:
    return sorted((cache / stage).rglob(f"*.{ext}"))


def _payload(p: Path) -> tuple[bytes, bytes]:
    """(checksum header, payload) of an envelope entry; the header is empty for a layout without one."""
    data = p.read_bytes()
    return (data[:70], data[70:]) if data[:5] in _MAGICS else (b"", data)


def _seal(p: Path, payload: bytes) -> bytes:
    """``payload`` with the checksum a deliberate editor would recompute for the entry's layout:
    HCE1 sha256(payload); HCE2 sha256 bound to the entry's name; no secret (HCM2 needs one)."""
    magic = p.read_bytes()[:5]
    if magic == b"HCE1 ":
        return magic + hashlib.sha256(payload).hexdigest().encode() + b"\n" + payload
    if magic in (b"HCE2 ", b"HCM2 "):
        rel = "/".join(p.parts[-3:])
        tag = hashlib.sha256(b"harness-stage-cache\0" + rel.encode() + b"\0" + payload).hexdigest()
        return b"HCE2 " + tag.encode() + b"\n" + payload
    return payload


def _edit_json(p: Path, fn, resign=False) -> None:
    head, payload = _payload(p)
    value = json.loads(payload)
    fn(value)
    new = json.dumps(value, sort_keys=True).encode()
    p.write_bytes(_seal(p, new) if resign else head + new)


def _flip(p: Path, at: float = 0.6) -> None:
    data = bytearray(p.read_bytes())
    data[int(len(data) * at)] ^= 0x10
    p.write_bytes(bytes(data))


def _truncate(p: Path) -> None:
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 2])


def _score_entry(cache: Path) -> Path:
    return _entries(cache, "score", "npy")[0]


def _metric_entry(cache: Path) -> Path:
    """The first metrics entry with a finite PSNR (an edit of +inf would leave its bytes unchanged)."""
    import math

    return next(p for p in _entries(cache, "metrics", "json") if math.isfinite(json.loads(_payload(p)[1])["psnr"]))


def _ten_scores(cache: Path) -> None:
    import io

    import numpy as np

    buf = io.BytesIO()
    np.save(buf, np.zeros(10))
    p = _score_entry(cache)
    p.write_bytes(_seal(p, buf.getvalue()))


def _edit_scene_in_place(scene: Path) -> None:
    st = scene.stat()
    with open(scene, "r+b") as f:
        f.seek(st.st_size - 100)
        b = f.read(1)
        f.seek(st.st_size - 100)
        f.write(bytes([b[0] ^ 0x01]))
    os.utime(scene, ns=(st.st_atime_ns, st.st_mtime_ns))


def _copy_over_another_key(cache: Path) -> None:
    """A metrics entry written over another key's, whose PSNR differs (random's over opacity's ...)."""
    entries = _entries(cache, "metrics", "json")
    psnr = {p: json.loads(_payload(p)[1])["psnr"] for p in entries}
    a = entries[0]
    b = next(p for p in entries if psnr[p] != psnr[a])
    shutil.copyfile(a, b)


def _swap_images(cache: Path) -> None:
    a, b = _entries(cache, "images", "png")[:2]
    da, db = a.read_bytes(), b.read_bytes()
    a.write_bytes(db)
    b.write_bytes(da)


def _replace(p: Path, make) -> None:
    p.unlink()
    make(p)


def _edit_texture(folder: Path) -> None:
    """Halve the opacity byte of every splat in sh0.webp (lossless, the same size)."""
    import numpy as np
    from PIL import Image

    tex = folder / "sh0.webp"
    with Image.open(tex) as im:
        px = np.asarray(im.convert("RGBA")).copy()
    px[..., 3] //= 2
    Image.fromarray(px, "RGBA").save(tex, format="WEBP", lossless=True)


def _plausible(cache: Path) -> None:
    """PSNR +0.5 dB, the checksum recomputed as a deliberate editor without the cache's key would."""
    _edit_json(_metric_entry(cache), lambda v: v.update(psnr=v["psnr"] + 0.5), resign=True)


#: id, what, damage(cache, scene), options: ratios (of the rerun), base ("grape" | "sog" | "keyed"),
#: compare ("rows" | "images" | "fresh" | "refused"), timeout, argv (replaces --cache ...), env
CACHE_EXPERIMENTS = [
    ("C1", "metrics entry: PSNR +10 dB (JSON edited)",
     lambda c, s: _edit_json(_metric_entry(c), lambda v: v.update(psnr=v["psnr"] + 10)), {}),
    ("C2", "metrics entry: PSNR NaN, checksum re-signed",
     lambda c, s: _edit_json(_metric_entry(c), lambda v: v.update(psnr=float("nan")), resign=True), {}),
    ("C3", "prune entry: splats_out 5734 > splats_in 5000 (edited)",
     lambda c, s: _edit_json(_entries(c, "prune", "json")[0], lambda v: v.update(splats_out=5734)), {}),
    ("C4", "prune entry: splats_out 5734, checksum re-signed",
     lambda c, s: _edit_json(_entries(c, "prune", "json")[0], lambda v: v.update(splats_out=5734), resign=True), {}),
    ("C5", "load entry edited (n_splats 4000)",
     lambda c, s: _edit_json(_entries(c, "load", "json")[0], lambda v: v.update(n_splats=4000)), {}),
    ("C6", "views entry edited (a test camera's fx doubled)",
     lambda c, s: _edit_json(_entries(c, "views", "json")[0], lambda v: v["test"][0].update(fx=v["test"][0]["fx"] * 2)),
     {}),
    ("C7", "views entry: camera 200000 px wide, checksum re-signed",
     lambda c, s: _edit_json(_entries(c, "views", "json")[0], lambda v: v["test"][0].update(width=200000),
                             resign=True), {}),
    ("C8", "scores byte-flipped, rerun adds ratio 0.5", lambda c, s: _flip(_score_entry(c)),
     {"ratios": "[0.1, 0.3, 0.5]"}),
    ("C9", "masks byte-flipped (every mask), rerun", lambda c, s: [_flip(p) for p in _entries(c, "masks", "npy")], {}),
    ("C10", "reference renders byte-flipped, rerun adds ratio 0.5",
     lambda c, s: [_flip(p) for p in _entries(c, "render_ref", "npy")], {"ratios": "[0.1, 0.3, 0.5]"}),
    ("C11", "10-element score array for the 5,000-splat scene (re-signed)", lambda c, s: _ten_scores(c),
     {"ratios": "[0.1, 0.3, 0.5]"}),
    ("C12", "scores entry truncated", lambda c, s: _truncate(_score_entry(c)), {}),
    ("C13", "mask entries truncated", lambda c, s: [_truncate(p) for p in _entries(c, "masks", "npy")], {}),
    ("C14", "render_ref records edited (width 65)",
     lambda c, s: [_edit_json(p, lambda v: v.update(width=65)) for p in _entries(c, "render_ref", "json")], {}),
    ("C15", "scene edited in place, same size, mtime restored", lambda c, s: _edit_scene_in_place(s),
     {"compare": "fresh"}),
    ("C16", "stale temporary files of a dead PID in the cache",
     lambda c, s: [(p.parent / f".{p.name}.{_host()}.999999.abcd.tmp").write_bytes(b"partial")
                   for p in _entries(c, "score", "npy")], {}),
    # ---- issue 24
    ("C17", "metrics entry copied over another key's (its PSNR differs)", lambda c, s: _copy_over_another_key(c), {}),
    ("C18", "two cached images swapped", lambda c, s: _swap_images(c), {"compare": "images"}),
    ("C19", "a cached image truncated", lambda c, s: _truncate(_entries(c, "images", "png")[0]), {"compare": "images"}),
    ("C20", "a FIFO in place of a metrics entry", lambda c, s: _replace(_metric_entry(c), os.mkfifo), {"timeout": 90}),
    ("C21", "a symlink to /dev/zero in place of a metrics entry",
     lambda c, s: _replace(_metric_entry(c), lambda p: p.symlink_to("/dev/zero")), {"timeout": 120}),
    ("C22", "SOG scene given as meta.json: one texture edited (opacity halved)", lambda c, s: _edit_texture(s.parent),
     {"base": "sog", "compare": "fresh"}),
    ("C23", "--cache memory:// with 2 workers (cold)", None, {"compare": "refused", "argv": [
        "--cache", "memory://harness-exp/stages", "--workers", "2"]}),
    ("C24", "metrics PSNR +0.5 dB, checksum recomputed (no cache key)", lambda c, s: _plausible(c), {}),
    ("C25", "the same with HARNESS_CACHE_KEY set (the editor lacks the key)", lambda c, s: _plausible(c),
     {"base": "keyed", "env": {"HARNESS_CACHE_KEY": KEY}}),
]


def _host() -> str:
    import re
    import socket

    return re.sub(r"[^A-Za-z0-9-]", "-", socket.gethostname())[:40] or "host"


def _sog_scene(folder: Path) -> Path:
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    from tests.test_sog_io import SogSpec

    SogSpec(3000, seed=7).write(folder, width=64)
    return folder / "meta.json"


def _base(root: Path, work: Path, kind: str, ratios: str) -> dict:
    """A clean study (its cache and results) of the base kind, run once and reused."""
    d = work / f"base-{kind}-{ratios.count(',')}"
    if (d / "done.json").exists():
        return json.loads((d / "done.json").read_text())
    d.mkdir(parents=True)
    if kind == "sog":
        scene = _sog_scene(d / "sog")
    else:
        scene = d / "g.ply"
        shutil.copy(Path(os.environ.get("HARNESS_SHARED_DATA", "/work/shared/data")) / "grape_small.ply", scene)
    env = {"HARNESS_CACHE_KEY": KEY} if kind == "keyed" else None
    t0 = time.perf_counter()
    r = harness(root, d, "run", str(_study(d, scene, ratios)), "--cache", str(d / "cache"), "--out", str(d / "out"),
                env=env)
    if r.returncode != 0:
        raise SystemExit(f"clean {kind} run failed: {r.stderr[-2000:]}")
    info = {"dir": str(d), "scene": str(scene), "seconds": round(time.perf_counter() - t0, 1)}
    (d / "done.json").write_text(json.dumps(info))
    return info


def _copy_scene(base_scene: Path, d: Path) -> Path:
    """The scene copied beside the experiment (a SOG folder whole), with its timestamps."""
    if base_scene.name == "meta.json":
        shutil.copytree(base_scene.parent, d / "sog")
        return d / "sog" / "meta.json"
    sc = d / base_scene.name
    shutil.copy2(base_scene, sc)
    return sc


def _outcome(eid, opts, r, d: Path, base: Path, root: Path, scene: Path) -> str:
    if r.returncode is None:
        return f"hang (killed after {opts.get('timeout', 300)} s)"
    lines = r.stderr.strip().splitlines() or [""]
    said = [ln for ln in (r.stderr + "\n" + r.stdout).splitlines() if ln.startswith(("harness:", "error:"))]
    last = (said[0] if said else lines[-1])[:110]  # the run's own words, else its last line
    if opts.get("compare") == "refused":
        made = (d / "out").exists()
        return f"exit {r.returncode}: {last}" + (" (output folder created)" if made else " (nothing created)")
    if r.returncode != 0:
        return f"exit {r.returncode}: {last}"
    warned = any("discarded" in ln for ln in (r.stderr + r.stdout).splitlines())
    if opts.get("compare") == "fresh":  # an edited scene: recomputed, and equal to a cold run on it
        f = d / "fresh"
        f.mkdir()
        harness(root, d, "run", str(d / "study.yaml"), "--cache", str(f / "cache"), "--out", str(f / "out"))
        counts = json.loads((d / "out" / "run.json").read_text()).get("cache_counts", {})
        recomputed = counts.get("load", {}).get("misses", 0) > 0
        same = _metrics(d / "out").equals(_metrics(f / "out"))
        if recomputed:
            return "recomputed" + (
                " (equals a cold run on the edited scene)" if same else ", yet DIFFERS from a cold run"
            )
        return "USED STALE RESULTS (cache hits on the old scene" + ("" if same else "; differs from a cold run") + ")"
    want = _metrics(base / "out")
    if not _metrics(d / "out").equals(want):
        return "RESULTS DIFFER (a bad entry was used)"
    if opts.get("compare") == "images" and _images(d / "out") != _images(base / "out"):
        return "IMAGES DIFFER (a bad cached image was used)"
    if eid == "C16":
        left = list((d / "cache").rglob("*.tmp"))
        return "swept" if not left else f"{len(left)} tmp left"
    return "discarded + recomputed" if warned else "results equal, no warning"


def cache_experiments(root: Path, work: Path, only: set | None = None) -> list[dict]:
    results = []
    for eid, what, damage, opts in CACHE_EXPERIMENTS:
        if only and eid not in only:
            continue
        ratios = opts.get("ratios", "[0.1, 0.3]")
        base = _base(root, work, opts.get("base", "grape"), "[0.1, 0.3]")
        want = Path(_base(root, work, opts.get("base", "grape"), ratios)["dir"])
        d = work / eid
        d.mkdir()
        scene = _copy_scene(Path(base["scene"]), d)
        argv = opts.get("argv")
        if argv is None:
            shutil.copytree(Path(base["dir"]) / "cache", d / "cache", symlinks=True)
            damage(d / "cache", scene)
            argv = ["--cache", str(d / "cache")]
        cfg = _study(d, scene, ratios)
        t0 = time.perf_counter()
        r = harness(root, d, "run", str(cfg), *argv, "--out", str(d / "out"), timeout=opts.get("timeout", 300),
                    env=opts.get("env"))
        secs = time.perf_counter() - t0
        warnings = [ln for ln in (r.stderr + r.stdout).splitlines() if "discarded" in ln]
        outcome = _outcome(eid, opts, r, d, want, root, scene)
        counts = {}
        if (d / "out" / "run.json").exists():
            counts = json.loads((d / "out" / "run.json").read_text()).get("cache_counts", {})
        results.append({"id": eid, "what": what, "outcome": outcome, "warnings": len(warnings),
                        "warning": warnings[0][:200] if warnings else "", "seconds": round(secs, 1),
                        "counts": counts})
        print(f"{eid:4s} {outcome[:70]:70s} {len(warnings)} warning(s) {secs:5.1f}s  {what}", flush=True)
        if warnings:
            print(f"       {warnings[0][:180]}", flush=True)
        shutil.rmtree(d, ignore_errors=True)
    return results


def table(before: list[dict], after: list[dict]) -> str:
    """Markdown: experiment, damage, before, after (with the first warning line after)."""
    b = {r["id"]: r for r in before}
    rows = ["| exp | damage | before | after |", "|---|---|---|---|"]
    for r in after:
        was = b.get(r["id"], {}).get("outcome", "(not run)")
        now = r["outcome"] + (f" — `{r['warning'].split('warning: ')[-1][:110]}`" if r.get("warning") else "")
        rows.append(f"| {r['id']} | {r['what']} | {was} | {now} |".replace("\n", " "))
    return "\n".join(rows)
