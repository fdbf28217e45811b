"""Executors: the Ray executor against the local one on the runner's fakes (tests/runner_fakes.py),
on one private 2-CPU Ray cluster shared by the module (no dashboard, no usage reports, no token).

What is checked: identical rows; a worker SIGKILLed in the middle of a task is retried and the
rows are still identical; an exception in a stage function is recorded once, named, never retried;
an exception that escapes a stage function is not retried either; a task whose worker dies on
every attempt fails after ``max_retries`` re-runs with its name; a cache folder that the cluster's
workers cannot see is refused before any work. The fsspec cache (``memory://``) runs in-process.
The real pipeline on ci.yaml (GL, LPIPS) is tests/test_ray_ci.py.
"""

from __future__ import annotations

import os
import shutil
import signal
import tempfile
import threading
import time
from pathlib import Path

import pytest

from harness.report.results import to_frame
from harness.run.config import parse_config
from harness.run.executors import Bars, RayExecutor, Stage
from harness.run.runner import Runner
from tests import runner_fakes as fakes

ray = pytest.importorskip("ray", reason="the ray package is not installed (pip install -e '.[test]')")
pytestmark = pytest.mark.ray

REPO = Path(__file__).resolve().parent.parent
#: every column of the rows except the wall-clock ones (they differ between any two runs)
TIMING = ["score_s", "prune_s", "render_ref_s", "render_s", "metrics_s"]


@pytest.fixture(scope="module")
def cluster():
    """One local cluster for the module (``ray.init`` takes ~5 s); the executors find it initialised
    and use it without stopping it."""
    from harness.run.executors import LOCAL_ENV, QUIET_ENV

    env = {**QUIET_ENV, **LOCAL_ENV}
    old = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    temp = tempfile.mkdtemp(prefix="ray-", dir="/tmp")  # AF_UNIX paths: pytest's tmp_path is too long
    cwd = os.getcwd()
    os.chdir(REPO)  # workers start in the driver's folder and import `tests` from there
    ray.init(address="local", num_cpus=2, num_gpus=0, include_dashboard=False, _temp_dir=temp,
             object_store_memory=256 * 2**20, logging_level="WARNING", log_to_driver=False)
    try:
        yield ray
    finally:
        ray.shutdown()
        os.chdir(cwd)
        shutil.rmtree(temp, ignore_errors=True)
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@pytest.fixture
def scenes(tmp_path):
    return fakes.write_two_scenes(tmp_path)


def _config(scenes, methods):
    return parse_config({
        "name": "t", "protocol": {"longest_side": 32, "metrics": ["psnr", "ssim"], "n_train": 3, "n_test": 2},
        "ratios": [0.1, 0.3], "scenes": [{"name": k, "source": v} for k, v in scenes.items()], "methods": methods,
    }, "test.yaml")


def _run(cfg, root: Path, executor=None, **kw):
    r = Runner(cfg, out_dir=root / "out", cache_root=kw.pop("cache", root / "cache"), toolkit=fakes.toolkit(),
               log=lambda m: None, executor=executor, **kw)
    res = r.run()
    return res, to_frame(res.rows).drop(columns=TIMING, errors="ignore")


def _ray(**kw):
    return RayExecutor(2, fakes.toolkit(), **kw)


def test_ray_rows_equal_local_rows(cluster, scenes, tmp_path):
    cfg = _config(scenes, ["fake-norm", "fake-aware", "opacity", {"name": "fake-norm", "variant": "same",
                                                                  "params": {"unused": 1}}])
    res_l, local = _run(cfg, tmp_path / "local")
    with _ray() as ex:
        res_r, remote = _run(cfg, tmp_path / "ray", executor=ex)
        assert ex.describe()["cluster_cpus"] == 2
    assert not res_l.errors and not res_r.errors
    assert (local["status"] == "ok").all() and len(local) == 2 * 4 * 2 * 2
    assert remote.equals(local)
    assert res_r.executor["name"] == "ray" and res_r.counts == res_l.counts
    # a rerun on Ray recomputes nothing and submits nothing
    with _ray() as ex:
        res2, again = _run(cfg, tmp_path / "ray", executor=ex)
    assert sum(c["misses"] for c in res2.counts.values()) == 0 and again.equals(local)


def _kill_first_attempt(marker: Path, stop: threading.Event, killed: list) -> None:
    """SIGKILL the worker that writes the first line of ``marker`` (once, while it sleeps in the task)."""
    while not stop.is_set():
        lines = marker.read_text().split() if marker.exists() else []
        if lines:
            time.sleep(0.3)  # well inside the task's sleep
            os.kill(int(lines[0]), signal.SIGKILL)
            killed.append(int(lines[0]))
            return
        time.sleep(0.05)


def test_killed_worker_is_retried_and_rows_are_identical(cluster, scenes, tmp_path):
    marker = tmp_path / "attempts"
    slow = {"name": "fake-slow", "params": {"seconds": 3.0, "marker": str(marker)}, "scenes": ["s1"]}
    cfg = _config(scenes, ["fake-norm", slow])
    _, local = _run(_config(scenes, ["fake-norm", {**slow, "params": {"seconds": 0.0, "marker": ""}}]),
                    tmp_path / "local")
    stop, killed = threading.Event(), []
    watcher = threading.Thread(target=_kill_first_attempt, args=(marker, stop, killed), daemon=True)
    watcher.start()
    try:
        with _ray() as ex:
            res, remote = _run(cfg, tmp_path / "ray", executor=ex)
    finally:
        stop.set()
        watcher.join(5)
    attempts = [int(x) for x in marker.read_text().split()]
    assert killed and len(attempts) == 2 and attempts[0] == killed[0] != attempts[1], attempts
    assert not res.errors, res.errors
    # fake-slow's params differ from the uninterrupted run's (marker, seconds): compare the rest
    assert remote.drop(columns=["params"]).equals(local.drop(columns=["params"]))
    # nothing half-written: every entry of the cache passes its checksum
    from harness.run.cache import StageCache

    audit = StageCache(tmp_path / "ray" / "cache").audit()
    assert audit and not {rel: why for rel, why in audit.items() if why}


def test_exception_in_a_stage_is_named_and_not_retried(cluster, scenes, tmp_path):
    marker = tmp_path / "attempts"
    cfg = _config(scenes, ["opacity", {"name": "fake-raise", "params": {"marker": str(marker)}, "scenes": ["s0"]}])
    with _ray() as ex:
        res, df = _run(cfg, tmp_path, executor=ex)
    assert len(marker.read_text().split()) == 1  # one attempt
    assert len(res.errors) == 1
    assert res.errors[0].startswith("score s0 fake-raise[default] (ratios 0.1, 0.3)"), res.errors
    assert "ValueError: fake-raise fails on purpose" in res.errors[0]
    assert set(df.loc[df["status"] == "error", "method"]) == {"fake-raise"}
    assert (df.loc[df["method"] == "opacity", "status"] == "ok").all()


def test_escaping_exception_fails_the_task_once_with_its_name(cluster, tmp_path):
    marker = tmp_path / "attempts"
    with _ray(max_retries=2) as ex:
        [[res]] = ex.run([Stage("score", fakes.escaping_task, [fakes.MarkerTask(str(marker), "s0 broken[x]")])],
                         Bars())
    assert len(marker.read_text().split()) == 1
    assert res["error"].startswith("score s0 broken[x]: KeyError"), res


def test_a_full_disk_on_a_node_ends_the_run(cluster, tmp_path):
    from harness.core.errors import StorageFull

    with _ray() as ex, pytest.raises(StorageFull, match="No space left on device"):
        ex.run([Stage("score", fakes.disk_full_task, [fakes.MarkerTask(str(tmp_path), "s0 full[x]")])], Bars())


def test_worker_dying_at_every_attempt_fails_after_the_retries(cluster, tmp_path):
    marker = tmp_path / "attempts"
    with _ray(max_retries=1) as ex:
        [[res]] = ex.run([Stage("score", fakes.crashing_task, [fakes.MarkerTask(str(marker), "s0 crash[x]")])],
                         Bars())
    assert len(marker.read_text().split()) == 2  # the attempt and one retry
    assert res["error"].startswith("score s0 crash[x]: the worker died 2 times"), res


def test_cache_the_workers_cannot_see_is_refused(cluster, tmp_path):
    """memory:// lives inside one process: to the workers it is like a folder of another machine."""
    from harness.core.errors import InputError

    with (
        _ray(cache_location="memory://harness-probe/cache") as ex,
        pytest.raises(InputError, match="not usable from Ray node"),
    ):
        ex.start()
    with _ray(cache_location=str(tmp_path)) as ex:  # a folder all (here: one) nodes see
        ex.start()


def test_fsspec_cache_url(scenes, tmp_path, monkeypatch):
    """A memory:// cache: entries PUT once each, a rerun hits everything, a damaged entry is recomputed."""
    import fsspec

    monkeypatch.setenv("HARNESS_CACHE", str(tmp_path / "harness-cache"))  # the images mirror
    url = "memory://harness-test/stages"
    cfg = _config(scenes, ["fake-norm", "opacity"])
    _, local = _run(cfg, tmp_path / "local")
    res, df = _run(cfg, tmp_path / "url", cache=url)
    assert df.equals(local) and not res.errors
    fs = fsspec.filesystem("memory")
    metrics = sorted(fs.glob("/harness-test/stages/metrics/*/*.json"))
    assert metrics and fs.glob("/harness-test/stages/images/*/*.png")
    assert not fs.glob("/harness-test/stages/**/*.tmp")
    fs.pipe_file(metrics[0], fs.cat_file(metrics[0])[:-3] + b"}}}")  # damaged after it was written
    res2, again = _run(cfg, tmp_path / "url2", cache=url)
    assert again.equals(local)
    assert res2.counts["metrics"]["misses"] == 1 and res2.counts["score"]["misses"] == 0
    # the images of a run are fetched from the URL into the run folder
    assert any(Path(p).exists() for p in res2.images.values())
    fs.rm("/harness-test", recursive=True)
