"""Issue 15's cache-corruption and kill experiments, run on real studies through the CLI.

    python -m tests.stress.experiments cache [--root TREE] [--json OUT] [--only C1,C17]
    python -m tests.stress.experiments kill  [--root TREE] [--json OUT]
    python -m tests.stress.experiments table BEFORE.json AFTER.json

**cache**: :mod:`tests.stress.cache_experiments` (a copy of a clean study's cache damaged one way
per experiment, the study rerun, its rows and images compared with the clean run's).

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

from tests.stress.cache_experiments import (
    STUDY,
    _env,  # noqa: F401  (the kill experiments' environment)
    cache_experiments,
    harness,
)

ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable


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
    ap.add_argument("which", choices=("cache", "kill", "table"))
    ap.add_argument("files", nargs="*", help="table: BEFORE.json AFTER.json of the cache experiments")
    ap.add_argument("--root", default=str(ROOT))
    ap.add_argument("--json", default=None)
    ap.add_argument("--only", default=None, help="cache experiment ids, comma-separated")
    args = ap.parse_args(argv)
    if args.which == "table":
        from tests.stress.cache_experiments import table

        before, after = (json.loads(Path(p).read_text()) for p in args.files)
        print(table(before, after))
        return 0
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
