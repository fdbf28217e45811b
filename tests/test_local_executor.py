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
