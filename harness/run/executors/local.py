"""The local executor: in-process (one worker) or a spawned process pool per stage."""

from __future__ import annotations

import os
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context

from harness.run.executors.base import Bars, Executor, Stage
from harness.run.tasks import init_worker, run_view


def _pool_worker_init(parent_pid: int, threads: int, imports, preload) -> None:
    """Pool initializer: die with the driver (even on its ``kill -9``), then :func:`init_worker`."""
    from harness.core.lifecycle import die_with_parent

    die_with_parent(parent_pid)
    init_worker(threads, imports, preload)


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

    The pool is started at the first stage that needs it and kept for the executor's life (closed by
    :meth:`close`), so the workers' imports, GL contexts and metric suites are paid once per run, not
    once per stage; a pool broken by a dead worker is replaced at the next stage."""

    name = "local"

    def __init__(self, workers: int = 1, toolkit=None, threads: int | None = None):
        from harness.run.toolkit import Toolkit

        self.workers = max(1, int(workers))
        self.toolkit = toolkit or Toolkit()
        self.threads = threads or max(1, (os.cpu_count() or 1) // self.workers)
        self.parallel = self.workers > 1
        self._pool: ProcessPoolExecutor | None = None

    def _get_pool(self) -> ProcessPoolExecutor:
        if self._pool is None or getattr(self._pool, "_broken", False):
            if self._pool is not None:
                _terminate(self._pool)
            self._pool = ProcessPoolExecutor(self.workers, mp_context=get_context("spawn"),
                                             initializer=_pool_worker_init,
                                             initargs=(os.getpid(), self.threads, self.toolkit.imports,
                                                       self.toolkit.preload))
        return self._pool

    def close(self) -> None:
        if self._pool is not None:
            pool, self._pool = self._pool, None
            if getattr(pool, "_broken", False):
                _terminate(pool)
            else:
                pool.shutdown(wait=True)

    def describe(self) -> dict:
        return {"name": self.name, "workers": self.workers, "threads": self.threads}

    def run(self, stages: Sequence[Stage], bars: Bars) -> list[list[dict]]:
        return [self._stage(s, bars) for s in stages]

    def _stage(self, stage: Stage, bars: Bars) -> list[dict]:
        results: list[dict] = []
        if not stage.tasks:  # everything cached: no worker start-up, no heavy imports
            return results
        weight = stage.weight
        bars.start(stage.name, sum(weight(t) for t in stage.tasks))
        if self.workers == 1 or len(stage.tasks) <= 1:
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
            pool = self._get_pool()
            try:
                futures = {pool.submit(stage.fn, t): t for t in stage.tasks}
                for fut in as_completed(futures):
                    try:
                        results.append(fut.result())
                    except Exception as err:  # a worker died (e.g. killed, segfault): record, go on
                        results.append(futures[fut].failed(f"worker failed: {type(err).__name__}: {err}"))
                    bars.advance(stage.name, weight(futures[fut]))
            except BaseException:  # SIGTERM / Ctrl-C / an error here: the workers go with the run
                self._pool = None
                _terminate(pool)
                raise
        bars.finish(stage.name)
        return results


