"""`harness run ctc_configs/ci.yaml --executor ray` on a local Ray cluster (2 CPUs, no dashboard) gives
the local executor's results.csv; so does a run whose Ray worker is SIGKILLed in the middle of a
render+metrics task (Ray re-runs the task on a fresh worker).

Compared: every column of results.csv except the five wall-clock timings (``score_s, prune_s,
render_ref_s, render_s, metrics_s``: seconds measured inside the tasks, different in any two runs),
in file order — scenes, methods, ratios, views, counts, bytes, τ and every metric value, bit for bit
(as written by pandas). Each run starts from an empty cache, so everything is computed by the
executor under test. Three cold runs of ci.yaml: about 2 minutes on 2 cores.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pandas as pd
import pytest

from harness.io.datasets import scene_path
from harness.metrics.lpips_weights import weights_path

pytest.importorskip("ray", reason="the ray package is not installed (setup.sh installs it)")
pytestmark = [pytest.mark.data, pytest.mark.gl, pytest.mark.weights, pytest.mark.ray]

REPO = Path(__file__).resolve().parent.parent
TIMING = ["score_s", "prune_s", "render_ref_s", "render_s", "metrics_s"]


def _cmd(tmp: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "harness", "run", str(REPO / "ctc_configs" / "ci.yaml"), "--out", str(tmp / "out"),
            "--cache", str(tmp / "cache"), *extra]


def _results(tmp: Path) -> pd.DataFrame:
    return pd.read_csv(tmp / "out" / "results.csv", keep_default_na=False, dtype=str).drop(columns=TIMING)


def _check(proc: subprocess.CompletedProcess | subprocess.Popen, out: str) -> None:
    if "GLUnavailable" in out:
        pytest.skip("no EGL context on this machine")
    assert proc.returncode == 0, out[-4000:]


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    for name in ("grape-small", "luigi"):
        if not scene_path(name).exists():
            pytest.skip(f"{name} is absent ({scene_path(name)}); run `harness fetch`")
    if not weights_path().is_file():
        pytest.skip("LPIPS weights absent; run `harness fetch --weights`")
    tmp = tmp_path_factory.mktemp("local")
    run = subprocess.run(_cmd(tmp, "--executor", "local", "--workers", "1"), capture_output=True, text=True,
                         timeout=900, cwd=REPO)
    _check(run, run.stdout + run.stderr)
    df = _results(tmp)
    assert len(df) == 2 * 52 and (df["status"] == "ok").all()  # 52 rows per view protocol (rig, shifted)
    return df


def test_ci_on_ray_equals_local(local, tmp_path):
    run = subprocess.run(_cmd(tmp_path, "--executor", "ray", "--workers", "2"), capture_output=True, text=True,
                         timeout=900, cwd=REPO)
    _check(run, run.stdout + run.stderr)
    assert "Ray (a local cluster of 2 worker(s))" in run.stderr
    pd.testing.assert_frame_equal(_results(tmp_path), local)
    import json

    record = json.loads((tmp_path / "out" / "run.json").read_text())
    assert record["executor"]["name"] == "ray" and record["executor"]["cluster_cpus"] == 2
    assert not record["errors"]


def _ancestors(pid: int) -> set[int]:
    out = set()
    while pid > 1:
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            break
        pid = int(stat.rsplit(")", 1)[1].split()[1])
        out.add(pid)
    return out


def _title(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")[0].decode(errors="replace")
    except OSError:
        return ""


def _kill_a_busy_worker(driver: int, prefix: str, stop: threading.Event, killed: list) -> None:
    """SIGKILL the first worker of ``driver``'s cluster seen running a ``prefix`` task for 0.5 s
    (its proctitle is ``ray::<task name>`` while the task runs, ``ray::IDLE`` otherwise)."""
    seen: dict[int, tuple[str, float]] = {}
    while not stop.is_set():
        for entry in os.listdir("/proc"):
            if not entry.isdigit():
                continue
            pid = int(entry)
            title = _title(pid)
            if not title.startswith(prefix) or driver not in _ancestors(pid):
                continue
            first = seen.setdefault(pid, (title, time.monotonic()))
            if first[0] == title and time.monotonic() - first[1] > 0.5 and _title(pid) == title:
                os.kill(pid, signal.SIGKILL)
                killed.append((pid, title))
                return
        time.sleep(0.05)


def test_ci_on_ray_with_a_worker_killed_mid_task_equals_local(local, tmp_path):
    proc = subprocess.Popen(_cmd(tmp_path, "--executor", "ray", "--workers", "2"), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, cwd=REPO, start_new_session=True)
    stop, killed = threading.Event(), []
    watcher = threading.Thread(target=_kill_a_busy_worker, args=(proc.pid, "ray::render+metrics[", stop, killed),
                               daemon=True)
    watcher.start()
    try:
        out, _ = proc.communicate(timeout=900)
    finally:
        stop.set()
        watcher.join(5)
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    _check(proc, out)
    assert killed, "no render+metrics task was seen running"
    pd.testing.assert_frame_equal(_results(tmp_path), local)
    # the kill left no torn entry: every cache entry passes its checksum
    from harness.run.cache import StageCache

    audit = StageCache(tmp_path / "cache").audit()
    assert audit and not {rel: why for rel, why in audit.items() if why}
