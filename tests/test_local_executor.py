"""The local executor keeps one process pool for the whole run: the workers (their imports, GL
contexts, metric suites) are started once, not once per stage; a pool broken by a dead worker is
replaced at the next stage."""

from __future__ import annotations

from harness.run.executors import Bars, LocalExecutor, Stage
from tests import runner_fakes as fakes


def _pids(results):
    return {r["pid"] for r in results}


def test_one_pool_serves_every_stage(tmp_path):
    tasks = [fakes.MarkerTask(str(tmp_path / "m"), f"t{i}") for i in range(6)]
    with LocalExecutor(2, fakes.toolkit(), threads=1) as ex:
        first, second = ex.run([Stage("a", fakes.pid_task, tasks), Stage("b", fakes.pid_task, tasks)], Bars())
        pool = ex._pool
        third = ex.run([Stage("c", fakes.pid_task, tasks)], Bars())[0]
        assert len(first) == len(second) == len(third) == 6
        assert ex._pool is pool  # the same pool, so the same (at most 2) workers served all three stages
        # which of the two workers a stage's tasks reach depends on their start-up: compare with all of them
        workers = set(pool._processes)
        assert _pids(first) | _pids(second) | _pids(third) <= workers and len(workers) <= 2
    assert ex._pool is None  # closed with the executor


def test_a_dead_worker_is_recorded_and_the_pool_replaced(tmp_path):
    marker = tmp_path / "attempts"
    with LocalExecutor(2, fakes.toolkit(), threads=1) as ex:
        # two tasks, so that the stage goes to the pool (a single task runs in this process)
        crashed = ex.run([Stage("score", fakes.crashing_task,
                                [fakes.MarkerTask(str(marker), "a"), fakes.MarkerTask(str(marker), "b")])], Bars())[0]
        assert all("worker failed" in r["error"] for r in crashed)
        after = ex.run([Stage("next", fakes.pid_task, [fakes.MarkerTask("", "x"), fakes.MarkerTask("", "y")])],
                       Bars())[0]
        assert len(after) == 2 and all("pid" in r for r in after)


def _on_device(task) -> bool:
    return task.label.startswith("dev")


def test_device_tasks_run_in_the_one_device_worker_and_the_rest_on_the_cpu_workers(tmp_path):
    tasks = [fakes.MarkerTask("", f"{'dev' if i % 3 == 0 else 'cpu'}{i}") for i in range(9)]
    with LocalExecutor(2, fakes.toolkit(), threads=1, device="cuda", device_workers=1) as ex:
        (res,) = ex.run([Stage("s", fakes.pid_task, tasks, on_device=_on_device)], Bars())
        dev = [r for r in res if r["label"].startswith("dev")]
        cpu = [r for r in res if r["label"].startswith("cpu")]
        assert len(dev) == 3 and len(cpu) == 6
        # the summary names the process that computed it, and the pools hold those processes
        assert all(r["worker"] == f"device {r['pid']}" for r in dev) and len(_pids(dev)) == 1
        assert all(r["worker"] == f"cpu {r['pid']}" for r in cpu)
        assert _pids(dev) <= set(ex._pools["device"]._processes) and len(ex._pools["device"]._processes) == 1
        assert _pids(cpu) <= set(ex._pools["cpu"]._processes) and not _pids(cpu) & _pids(dev)
        assert ex.describe()["device_workers"] == 1 and ex.describe()["tasks"] == {"s": {"cpu": 6, "device": 3}}
        # one task of a GPU run still goes to its worker (the driver never opens the device)
        (one,) = ex.run([Stage("t", fakes.pid_task, tasks[:1], on_device=_on_device)], Bars())
        assert one[0]["worker"].startswith("device ")
    assert ex._pools == {}


def test_on_the_cpu_there_is_one_pool_and_no_device_worker(tmp_path):
    tasks = [fakes.MarkerTask("", f"dev{i}") for i in range(4)]
    with LocalExecutor(2, fakes.toolkit(), threads=1, device="cpu", device_workers=3) as ex:
        (res,) = ex.run([Stage("s", fakes.pid_task, tasks, on_device=_on_device)], Bars())
        assert ex.device_workers == 0 and set(ex._pools) == {"cpu"}
        assert all(r["worker"].startswith("cpu ") for r in res)
        assert ex.describe() == {"name": "local", "workers": 2, "threads": 1}


def test_a_full_disk_ends_the_run_instead_of_failing_one_task(tmp_path):
    """Every later write would fail too: the error reaches the caller (the CLI's one line, exit 2),
    with one worker and with a pool, rather than being recorded against each task in turn."""
    import errno

    import pytest

    from harness.core.errors import StorageFull, task_error
    from harness.io.files import atomic_write_with

    def full(tmp):
        raise OSError(errno.EFBIG, "File too large")

    with pytest.raises(StorageFull, match=r"out\.bin: cannot write: File too large \(the storage is full"):
        atomic_write_with(tmp_path / "out.bin", full)
    assert not list(tmp_path.iterdir())  # no temporary left behind
    assert task_error(ValueError("x")) == "ValueError: x"  # any other error is the task's own
    tasks = [fakes.MarkerTask(str(tmp_path), f"t{i}") for i in range(2)]
    for workers in (1, 2):
        with LocalExecutor(workers, fakes.toolkit(), threads=1) as ex, \
                pytest.raises(StorageFull, match="No space left on device"):
            ex.run([Stage("score", fakes.disk_full_task, tasks)], Bars())
