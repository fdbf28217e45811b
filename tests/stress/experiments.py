"""Issue 15's cache-corruption and kill experiments, run on real studies through the CLI.

    python -m tests.stress.experiments cache [--root TREE] [--json OUT]
    python -m tests.stress.experiments kill  [--root TREE] [--json OUT]

**cache**: a small study (grape-small, 5,000 splats; opacity + random pruners; 2 ratios; 2 views;
PSNR/SSIM/LPIPS at 64 px) is run once cold; then, for each experiment, a copy of that cache is
damaged in one way and the study rerun (some with an added ratio, so cached scores, masks and
reference renders are read to compute new rows). An experiment passes when the rerun exits 0
and its metric rows equal the clean run's to the bit (the bad entry was not used: it was
discarded with a warning and recomputed), or — for the edited scene — when the scene's stages were
recomputed instead of hit.

**kill**: SIGTERM and ``kill -9`` of ``harness prune`` at several instants (temporary files left?
cleaned by the next command?), and of ``harness run --workers 2`` (do the pool's workers and the
resource tracker survive the driver? does a rerun resume and finish?).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable

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


def _env(root: Path) -> dict:
    return {**os.environ, "PYTHONPATH": str(root), "HARNESS_SHARED_DATA": os.environ.get(
        "HARNESS_SHARED_DATA", "/work/shared/data"), "PYTHONWARNINGS": "ignore"}


def harness(root: Path, cwd: Path, *argv, timeout=300) -> subprocess.CompletedProcess:
    """Run the CLI; a run past ``timeout`` is killed (with its process group) and reported with
    ``returncode`` None."""
    proc = subprocess.Popen([PY, "-m", "harness", *argv], cwd=cwd, env=_env(root), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL, start_new_session=True)
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


def _entries(cache: Path, stage: str, ext: str) -> list[Path]:
    return sorted((cache / stage).rglob(f"*.{ext}"))


def _payload(p: Path) -> tuple[bytes, bytes]:
    """(checksum header, payload) of an entry; the header is empty for the pre-issue-15 layout."""
    data = p.read_bytes()
    return (data[:70], data[70:]) if data.startswith(b"HCE1 ") else (b"", data)


def _resign(p: Path, payload: bytes) -> None:
    """Write ``payload`` with a valid checksum (the old layout had none: the payload alone)."""
    import hashlib

    if p.read_bytes().startswith(b"HCE1 "):
        payload = b"HCE1 " + hashlib.sha256(payload).hexdigest().encode() + b"\n" + payload
    p.write_bytes(payload)


def _edit_json(p: Path, fn, resign=False) -> None:
    head, payload = _payload(p)
    value = json.loads(payload)
    fn(value)
    new = json.dumps(value, sort_keys=True).encode()
    if resign:
        _resign(p, new)
    else:
        p.write_bytes(head + new)


def _flip(p: Path, at: float = 0.6) -> None:
    data = bytearray(p.read_bytes())
    i = int(len(data) * at)
    data[i] ^= 0x10
    p.write_bytes(bytes(data))


def _truncate(p: Path) -> None:
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 2])


def _score_entry(cache: Path) -> Path:
    return _entries(cache, "score", "npy")[0]


def _metric_entry(cache: Path) -> Path:
    return _entries(cache, "metrics", "json")[0]


def _ten_scores(cache: Path) -> None:
    import io

    import numpy as np

    buf = io.BytesIO()
    np.save(buf, np.zeros(10))
    _resign(_score_entry(cache), buf.getvalue())


def _edit_scene_in_place(scene: Path) -> None:
    st = scene.stat()
    with open(scene, "r+b") as f:
        f.seek(st.st_size - 100)
        b = f.read(1)
        f.seek(st.st_size - 100)
        f.write(bytes([b[0] ^ 0x01]))
    os.utime(scene, ns=(st.st_atime_ns, st.st_mtime_ns))


#: (id, what, damage(cache, scene), ratios of the rerun)
CACHE_EXPERIMENTS = [
    ("C1", "metrics entry: PSNR +10 dB (JSON edited)",
     lambda c, s: _edit_json(_metric_entry(c), lambda v: v.update(psnr=v["psnr"] + 10)), None),
    ("C2", "metrics entry: PSNR NaN, checksum re-signed",
     lambda c, s: _edit_json(_metric_entry(c), lambda v: v.update(psnr=float("nan")), resign=True), None),
    ("C3", "prune entry: splats_out 5734 > splats_in 5000 (edited)",
     lambda c, s: _edit_json(_entries(c, "prune", "json")[0], lambda v: v.update(splats_out=5734)), None),
    ("C4", "prune entry: splats_out 5734, checksum re-signed",
     lambda c, s: _edit_json(_entries(c, "prune", "json")[0], lambda v: v.update(splats_out=5734), resign=True),
     None),
    ("C5", "load entry edited (n_splats 4000)",
     lambda c, s: _edit_json(_entries(c, "load", "json")[0], lambda v: v.update(n_splats=4000)), None),
    ("C6", "views entry edited (a test camera's fx doubled)",
     lambda c, s: _edit_json(_entries(c, "views", "json")[0], lambda v: v["test"][0].update(fx=v["test"][0]["fx"] * 2)),
     None),
    ("C7", "views entry: camera 200000 px wide, checksum re-signed",
     lambda c, s: _edit_json(_entries(c, "views", "json")[0], lambda v: v["test"][0].update(width=200000),
                             resign=True), None),
    ("C8", "scores byte-flipped, rerun adds ratio 0.5", lambda c, s: _flip(_score_entry(c)), "[0.1, 0.3, 0.5]"),
    ("C9", "masks byte-flipped (every mask), rerun", lambda c, s: [_flip(p) for p in _entries(c, "masks", "npy")],
     None),
    ("C10", "reference renders byte-flipped, rerun adds ratio 0.5",
     lambda c, s: [_flip(p) for p in _entries(c, "render_ref", "npy")], "[0.1, 0.3, 0.5]"),
    ("C11", "10-element score array for the 5,000-splat scene (re-signed)", lambda c, s: _ten_scores(c),
     "[0.1, 0.3, 0.5]"),
    ("C12", "scores entry truncated", lambda c, s: _truncate(_score_entry(c)), None),
    ("C13", "mask entries truncated", lambda c, s: [_truncate(p) for p in _entries(c, "masks", "npy")], None),
    ("C14", "render_ref records edited (width 65)",
     lambda c, s: [_edit_json(p, lambda v: v.update(width=65)) for p in _entries(c, "render_ref", "json")], None),
    ("C15", "scene edited in place, same size, mtime restored", lambda c, s: _edit_scene_in_place(s), None),
    ("C16", "stale temporary files of a dead PID in the cache",
     lambda c, s: [(p.parent / f".{p.name}.{_host()}.999999.abcd.tmp").write_bytes(b"partial")
                   for p in _entries(c, "score", "npy")], None),
]


def _host() -> str:
    import re
    import socket

    return re.sub(r"[^A-Za-z0-9-]", "-", socket.gethostname())[:40] or "host"


def cache_experiments(root: Path, work: Path, only: set | None = None) -> list[dict]:
    src_scene = Path(os.environ.get("HARNESS_SHARED_DATA", "/work/shared/data")) / "grape_small.ply"
    base = work / "base"
    base.mkdir(parents=True)
    scene = base / "g.ply"
    shutil.copy(src_scene, scene)
    cfg = _study(base, scene)
    t0 = time.perf_counter()
    r = harness(root, base, "run", str(cfg), "--cache", str(base / "cache"), "--out", str(base / "out"))
    cold = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(f"clean run failed: {r.stderr[-2000:]}")
    clean = _metrics(base / "out")
    # the clean reference of the runs that add ratio 0.5
    cfg3 = _study(base, scene, "[0.1, 0.3, 0.5]")
    harness(root, base, "run", str(cfg3), "--cache", str(base / "cache3"), "--out", str(base / "out3"))
    clean3 = _metrics(base / "out3")
    print(f"clean run {cold:.1f} s: {len(clean)} metric rows", flush=True)
    results = []
    for eid, what, damage, ratios in CACHE_EXPERIMENTS:
        if only and eid not in only:
            continue
        d = work / eid
        d.mkdir()
        shutil.copytree(base / "cache", d / "cache")
        sc = d / "g.ply"
        shutil.copy(scene, sc)
        os.utime(sc, ns=(scene.stat().st_atime_ns, scene.stat().st_mtime_ns))
        damage(d / "cache", sc)
        cfg_e = _study(d, sc, ratios or "[0.1, 0.3]")
        t0 = time.perf_counter()
        r = harness(root, d, "run", str(cfg_e), "--cache", str(d / "cache"), "--out", str(d / "out"))
        secs = time.perf_counter() - t0
        warnings = [ln for ln in (r.stderr + r.stdout).splitlines() if "discarded" in ln]
        run_json = json.loads((d / "out" / "run.json").read_text()) if (d / "out" / "run.json").exists() else {}
        counts = run_json.get("cache_counts", {})
        tmp_left = [p for p in (d / "cache").rglob("*.tmp")]
        if r.returncode is None:
            outcome = "hang (killed after 300 s)"
        elif r.returncode != 0:
            outcome = f"exit {r.returncode}: {(r.stderr.strip().splitlines() or [''])[-1][:100]}"
        elif eid == "C15":
            changed = counts.get("load", {}).get("misses", 0) > 0 and counts.get("score", {}).get("hits", 1) == 0
            outcome = "recomputed (new scene digest)" if changed else "USED STALE RESULTS"
        else:
            got = _metrics(d / "out")
            want = clean3 if ratios else clean
            same = got.equals(want)
            if not same:
                outcome = "RESULTS DIFFER (a bad entry was used)"
            elif eid == "C16":
                outcome = "swept" if not tmp_left else f"{len(tmp_left)} tmp left"
            else:
                outcome = "discarded + recomputed" if warnings else "results equal, no warning"
        results.append({"id": eid, "what": what, "outcome": outcome, "warnings": len(warnings),
                        "warning": warnings[0][:200] if warnings else "", "seconds": round(secs, 1),
                        "counts": counts})
        print(f"{eid:4s} {outcome:40s} {len(warnings)} warning(s) {secs:5.1f}s  {what}", flush=True)
        if warnings:
            print(f"       {warnings[0][:180]}", flush=True)
        shutil.rmtree(d, ignore_errors=True)
    return results


# ----------------------------------------------------------------------------- kill experiments
def _children(pid: int) -> list[int]:
    """Every descendant of ``pid`` (from /proc)."""
    kids: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                ppid = int(f.read().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        kids.setdefault(ppid, []).append(int(entry))
    out, todo = [], [pid]
    while todo:
        for c in kids.get(todo.pop(), []):
            out.append(c)
            todo.append(c)
    return out


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _cmdline(pid: int) -> str:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read().replace(b"\0", b" ").decode(errors="replace")[:120]
    except OSError:
        return "?"


def _rss_mb(pid: int) -> int:
    try:
        with open(f"/proc/{pid}/status") as f:
            return next(int(ln.split()[1]) // 1024 for ln in f if ln.startswith("VmRSS"))
    except (OSError, StopIteration, ValueError):
        return 0


def _tmps(d: Path) -> list[Path]:
    return [p for p in d.rglob(".*.tmp")]


def kill_experiments(root: Path, work: Path) -> list[dict]:
    results = []
    scene_src = Path.home() / ".cache" / "harness" / "data" / "bonsai-7k-mini.splat"
    # -- prune: SIGTERM / SIGKILL at several instants; the output is written last (~70 MB .ply)
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for delay in (0.0, 0.02, 0.05, 0.1, 0.2):
            d = work / f"prune-{sig.name}-{delay}"
            d.mkdir(parents=True)
            proc = subprocess.Popen([PY, "-m", "harness", "prune", str(scene_src), str(d / "out.ply"), "--ratio",
                                     "0.3", "--method", "opacity"], cwd=d, env=_env(root),
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL)
            # wait until the output's temporary file exists (the write has begun), then signal
            # ``delay`` seconds into the write
            while proc.poll() is None and not list(d.glob(".out.ply.*")):
                time.sleep(0.002)
            time.sleep(delay)
            proc.send_signal(sig)
            out, err = proc.communicate(timeout=60)
            left = _tmps(d)
            written = (d / "out.ply").exists()
            # the next command writing into the folder sweeps what a kill -9 left
            r2 = harness(root, d, "prune", str(scene_src), str(d / "out2.ply"), "--ratio", "0.3", "--method", "opacity")
            after = _tmps(d)
            rec = {"id": f"prune {sig.name} {delay:.2f} s into the write", "rc": proc.returncode,
                   "tmp_left": len(left),
                   "output_written": written, "tmp_after_next_command": len(after), "next_rc": r2.returncode,
                   "stderr": err.decode(errors="replace").strip()[-120:]}
            if written:
                sys.path.insert(0, str(ROOT))
                from harness.io.ply import read_ply

                rec["output_complete"] = len(read_ply(d / "out.ply")) > 0
            results.append(rec)
            print(json.dumps(rec), flush=True)
            shutil.rmtree(d, ignore_errors=True)
    # -- run --workers 2: kill -9 / SIGTERM of the driver while its pool works
    for sig in (signal.SIGKILL, signal.SIGTERM):
        d = work / f"run-{sig.name}"
        d.mkdir(parents=True)
        scene = Path(os.environ.get("HARNESS_SHARED_DATA", "/work/shared/data")) / "grape_small.ply"
        cfg = d / "study.yaml"
        cfg.write_text(STUDY.replace("RATIOS", "[0.1, 0.2, 0.3, 0.4, 0.5]").replace("SCENE", str(scene))
                       .replace("n_test: 2", "n_test: 6").replace("longest_side: 64", "longest_side: 256"))
        # output to files, not pipes: workers that outlive the driver would hold a pipe open forever
        log = open(d / "stderr.txt", "wb")
        proc = subprocess.Popen([PY, "-m", "harness", "run", str(cfg), "--workers", "2", "--cache", str(d / "cache"),
                                 "--out", str(d / "out")], cwd=d, env=_env(root), stdout=subprocess.DEVNULL,
                                stderr=log, stdin=subprocess.DEVNULL)
        workers: list[int] = []
        t0 = time.time()
        while time.time() - t0 < 120 and proc.poll() is None:
            kids = [k for k in _children(proc.pid) if "spawn_main" in _cmdline(k)
                    or "resource_tracker" in _cmdline(k) or "multiprocessing" in _cmdline(k)]
            if len([k for k in kids if "spawn_main" in _cmdline(k)]) >= 2:
                workers = kids
                break
            time.sleep(0.2)
        time.sleep(2.0)
        workers = sorted(set(workers) | {k for k in _children(proc.pid)})
        names = {k: _cmdline(k) for k in workers}
        proc.send_signal(sig)
        proc.wait(timeout=120)
        log.close()
        err = (d / "stderr.txt").read_bytes()
        time.sleep(3.0)
        survivors = [k for k in workers if _alive(k)]
        rss = {k: _rss_mb(k) for k in survivors}
        tmp_left = _tmps(d)
        for k in survivors:  # leave the machine as found (they are this experiment's own processes)
            try:
                os.kill(k, signal.SIGKILL)
            except OSError:
                pass
        r2 = harness(root, d, "run", str(cfg), "--workers", "2", "--cache", str(d / "cache"), "--out", str(d / "out"))
        rec = {"id": f"run --workers 2, {sig.name} of the driver", "rc": proc.returncode,
               "children_before": len(workers),
               "children": [("tracker" if "resource_tracker" in n else "worker" if "spawn_main" in n else n[:40])
                            for n in names.values()],
               "survivors": [f"{'tracker' if 'resource_tracker' in names[k] else 'worker'} ({rss[k]} MB)"
                             for k in survivors], "tmp_left": len(tmp_left),
               "rerun_rc": r2.returncode, "stderr": err.decode(errors="replace").strip()[-160:]}
        results.append(rec)
        print(json.dumps(rec), flush=True)
        for k in survivors:  # leave the machine as found
            try:
                os.kill(k, signal.SIGKILL)
            except OSError:
                pass
        shutil.rmtree(d, ignore_errors=True)
    return results


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("which", choices=("cache", "kill"))
    ap.add_argument("--root", default=str(ROOT))
    ap.add_argument("--json", default=None)
    ap.add_argument("--only", default=None, help="cache experiment ids, comma-separated")
    args = ap.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix=f"exp-{args.which}-"))
    try:
        if args.which == "cache":
            res = cache_experiments(Path(args.root), work, set(args.only.split(",")) if args.only else None)
        else:
            res = kill_experiments(Path(args.root), work)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
