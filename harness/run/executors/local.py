"""The local executor: in-process (one worker) or spawned process pools (CPU workers, and on a GPU run
the device workers, :mod:`harness.run.executors.device`)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context

from harness.core.errors import task_error
from harness.run.executors.base import Bars, Executor, Stage
from harness.run.executors.device import device_worker_count
from harness.run.tasks import init_worker, run_view

#: the two kinds of pool worker: CPU stages, and the tasks that compute on the run's device
ROLES = ("cpu", "device")


def _pool_worker_init(parent_pid: int, threads: int, imports, preload) -> None:
    """Pool initializer: die with the driver (even on its ``kill -9``), then :func:`init_worker`."""
    from harness.core.lifecycle import die_with_parent

    die_with_parent(parent_pid)
    init_worker(threads, imports, preload)


def _tagged(fn, task, role: str):
    """``fn(task)`` in a pool worker, its summary marked with where it ran: ``"cpu <pid>"`` / ``"device <pid>"``."""
    out = fn(task)
    if isinstance(out, dict):
        out["worker"] = f"{role} {os.getpid()}"
    return out


def _terminate(pool: ProcessPoolExecutor) -> None:
    """Stop a pool now: cancel what is queued, SIGTERM then SIGKILL every worker, reap them."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        if p.is_alive():
            p.terminate()
    for p in procs:
        p.join(timeout=2.0)
        if p.is_alive():
            p.kill()
            p.join(timeout=2.0)


class LocalExecutor(Executor):
    """In-process (one worker) or a spawned process pool, ``cores // workers`` threads each.

    The pools are started at the first stage that needs them and kept for the executor's life (closed
    by :meth:`close`), so the workers' imports, GL contexts and metric suites are paid once per run,
    not once per stage; a pool broken by a dead worker is replaced at the next stage.

    On a GPU run (``device`` not the CPU, more than one worker) a stage's tasks for which
    ``stage.on_device(task)`` holds go to a second pool of ``device_workers`` processes (0: by the
    device's free memory, :func:`harness.run.executors.device.device_worker_count`), the others to the
    ``workers`` CPU processes, which therefore never open the device; on the CPU there is one pool,
    as before. Each pool task's summary says where it ran (``"worker": "cpu <pid>"``)."""

    name = "local"

    def __init__(self, workers: int = 1, toolkit=None, threads: int | None = None, device: str = "cpu",
                 device_workers: int = 0):
        from harness.run.toolkit import Toolkit

        self.workers = max(1, int(workers))
        self.toolkit = toolkit or Toolkit()
        self.threads = threads or max(1, (os.cpu_count() or 1) // self.workers)
        self.parallel = self.workers > 1
        self.device = device
        self.device_workers = device_worker_count(device, self.workers, device_workers)
        self._pools: dict[str, ProcessPoolExecutor] = {}
        #: stage -> role -> tasks run there (GPU runs: what run.json's executor record shows)
        self.routed: dict[str, dict[str, int]] = {}

    @property
    def _pool(self) -> ProcessPoolExecutor | None:
        """The CPU workers' pool (None before the first stage that needs it, and once closed)."""
        return self._pools.get("cpu")

    def _get_pool(self, role: str = "cpu") -> ProcessPoolExecutor:
        pool = self._pools.get(role)
        if pool is None or getattr(pool, "_broken", False):
            if pool is not None:
                _terminate(pool)
            size = self.device_workers if role == "device" else self.workers
            pool = self._pools[role] = ProcessPoolExecutor(
                size, mp_context=get_context("spawn"), initializer=_pool_worker_init,
                initargs=(os.getpid(), self.threads, self.toolkit.imports, self.toolkit.preload))
        return pool

    def close(self) -> None:
        pools, self._pools = self._pools, {}
        for pool in pools.values():
            if getattr(pool, "_broken", False):
                _terminate(pool)
            else:
                pool.shutdown(wait=True)

    def describe(self) -> dict:
        d = {"name": self.name, "workers": self.workers, "threads": self.threads}
        if self.device_workers:
            d.update(device=self.device, device_workers=self.device_workers, tasks=self.routed)
        return d

    def run(self, stages: Sequence[Stage], bars: Bars) -> list[list[dict]]:
        return [self._stage(s, bars) for s in stages]

    def _stage(self, stage: Stage, bars: Bars) -> list[dict]:
        results: list[dict] = []
        if not stage.tasks:  # everything cached: no worker start-up, no heavy imports
            return results
        weight = stage.weight
        bars.start(stage.name, sum(weight(t) for t in stage.tasks))
        if self.workers == 1 or (len(stage.tasks) <= 1 and not self.device_workers):
            init_worker(self.threads, self.toolkit.imports, self.toolkit.preload)
            for t in stage.tasks:
                done = [0]  # units the task reported itself (a view task reports each measured set)

                def report(n=1, done=done):
                    done[0] += n
                    bars.advance(stage.name, n)

                results.append(stage.fn(t, progress=report) if stage.fn is run_view else stage.fn(t))
                if weight(t) > done[0]:  # the rest of its weight (e.g. a reference render)
                    bars.advance(stage.name, weight(t) - done[0])
        else:
            self._in_pools(stage, bars, results)
        bars.finish(stage.name)
        return results

    def _role(self, stage: Stage, task) -> str:
        return "device" if self.device_workers and stage.on_device(task) else "cpu"

    def _in_pools(self, stage: Stage, bars: Bars, results: list[dict]) -> None:
        """The stage's tasks on the pools (each to its role's), summaries appended as they finish."""
        futures = {}
        try:
            for t in stage.tasks:
                role = self._role(stage, t)
                futures[self._get_pool(role).submit(_tagged, stage.fn, t, role)] = t
                if self.device_workers:
                    counts = self.routed.setdefault(stage.name, dict.fromkeys(ROLES, 0))
                    counts[role] += 1
            for fut in as_completed(futures):
                try:
                    results.append(fut.result())
                except Exception as err:  # a worker died (e.g. killed, segfault): record, go on
                    results.append(futures[fut].failed(f"worker failed: {task_error(err)}"))
                bars.advance(stage.name, stage.weight(futures[fut]))
        except BaseException:  # SIGTERM / Ctrl-C / an error here: the workers go with the run
            pools, self._pools = self._pools, {}
            for pool in pools.values():
                _terminate(pool)
            raise
