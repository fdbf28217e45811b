"""Where a run's work units execute: this process / a local process pool, or a Ray cluster.

The runner hands an executor a list of :class:`Stage` s (name, stage function, task descriptions,
progress weight per task) and gets back every task's summary; the stage functions
(:func:`harness.run.tasks.run_score`, :func:`harness.run.tasks.run_view`) are the same everywhere
and store their results in the content-addressed stage cache, which is what makes executors
interchangeable: the rows of a run are read from the cache afterwards.

* :class:`LocalExecutor` (the default): one worker computes in-process; more workers are a spawned
  :class:`~concurrent.futures.ProcessPoolExecutor` kept for the run (``cores // workers`` threads
  each, killed with the driver). Stages run one after the other. On a GPU run the tasks that compute
  on the device (a stage's ``on_device``) go to a few device workers of their own, the rest to the
  CPU workers, which never open the device (:mod:`harness.run.executors.device`).
* :class:`RayExecutor` (``harness run --executor ray [--address ...]``): every task is a Ray task
  with a resource request (``cpus_per_task`` CPUs; a GPU share when ``protocol.device`` is CUDA and
  the cluster has GPUs). Stages given together (the reference renders and the pruned renders of
  the views) are one pipeline: a view's pruned sets start as soon as its reference is rendered.
  A scene is loaded **once** per stage call, by a Ray task, into the object store, and every task
  of that scene receives it by reference (zero copy on the node); a reference render is returned
  by its task into the object store and handed to the view's pruned-set tasks. Tasks are submitted
  grouped by scene and view, at most ``window`` at a time, and the driver drops its handles once
  the last consumer is submitted, so the object store holds a few scenes and views, not the run.

  Failures: an exception in a stage function is recorded by the function itself (its summary
  carries the error; the run goes on and exits 1, naming scene/method/ratio); an exception that
  escapes it fails that task at once (``retry_exceptions=False``: deterministic, never retried). A
  worker process that dies (killed, out of memory, segfault) is retried ``max_retries`` times
  (Ray's system-failure retries); a retried task recomputes its entries, which is idempotent
  because the cache is content-addressed and publishes every entry atomically. A task whose
  worker died on every attempt is recorded as failed with its description.

  Worker processes are long-lived (per-process state: the scene last loaded, one GL context, the
  metric suite); each runs :func:`harness.run.tasks.init_worker` once before its first task (thread
  caps, then the toolkit's ``preload`` modules, then plugins).

Before anything is created, :func:`preflight` checks that the cache location serves this executor
(``memory://`` only for one local worker) and that a Ray address answers within 10 s.
"""

from __future__ import annotations

from harness.run.executors.base import Bars, Executor, Stage
from harness.run.executors.local import LocalExecutor
from harness.run.executors.preflight import preflight
from harness.run.executors.ray_cluster import LOCAL_ENV, QUIET_ENV, RayExecutor

__all__ = ["LOCAL_ENV", "QUIET_ENV", "Bars", "Executor", "LocalExecutor", "RayExecutor", "Stage", "make_executor",
           "preflight"]


def make_executor(spec, workers: int, *, toolkit=None, device: str = "cpu", cache_location: str | None = None,
                  threads: int | None = None, log=print) -> Executor:
    """The executor a :class:`harness.run.config.ExecutorSpec` names (Ray is started lazily, at the
    first stage with work, so a fully cached rerun starts no cluster). ``threads``: per worker
    (default ``cores // workers``; for Ray it overrides ``cpus_per_task``)."""
    if spec.name == "ray":
        return RayExecutor(workers, toolkit, address=spec.address, cpus_per_task=threads or spec.cpus_per_task,
                           gpus_per_task=spec.gpus_per_task, max_retries=spec.max_retries, device=device,
                           cache_location=cache_location, log=log)
    return LocalExecutor(workers, toolkit, threads=threads, device=device, device_workers=spec.device_workers)
