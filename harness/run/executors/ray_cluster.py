"""The Ray executor (``harness run --executor ray [--address ...]``); see :mod:`harness.run.executors`."""

from __future__ import annotations

import logging
import os
import re
import shutil
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from harness.core.errors import InputError, StorageFull
from harness.run.executors.base import Bars, Executor, Stage
from harness.run.tasks import init_worker, run_view

#: environment of every Ray process this driver starts or connects with: no usage reports to an
#: external URL (the minimal dashboard head would POST them); set before ray.init, inherited
QUIET_ENV = {"RAY_USAGE_STATS_ENABLED": "0", "RAY_DEDUP_LOGS": "0"}
#: a private local cluster needs no token (Ray >= 2.5x enables token auth for a fresh ray.init and
#: writes ~/.ray/auth_token); a real cluster keeps its auth and the user supplies the token
LOCAL_ENV = {"RAY_AUTH_MODE": "disabled"}
_ANSI = re.compile(r"\x1b\[[0-9;]*m")
_WORKER_SETUP: tuple | None = None


def _setup_worker(threads: int, imports: tuple, preload: tuple) -> None:
    """Once per Ray worker process (and again if a later run asks for other threads/plugins)."""
    global _WORKER_SETUP
    key = (threads, tuple(imports), tuple(preload))
    if _WORKER_SETUP != key:
        import warnings

        # arrays from the object store are read-only: torch.as_tensor warns about every one it wraps.
        # Nothing writes into a scene or a reference render (a write would raise, not corrupt).
        warnings.filterwarnings("ignore", message="The given NumPy array is not writable")
        init_worker(threads, imports, preload)
        _WORKER_SETUP = key


def _ray_call(fn, setup, task, scene, ref):
    """A stage function in a Ray worker; ``scene``/``ref`` arrive resolved from the object store."""
    _setup_worker(*setup)
    if fn is run_view:
        return fn(task, scene=scene, ref=ref)
    return fn(task, scene=scene)


def _ray_call_keep_ref(fn, setup, task, scene, ref):
    """A view task that renders its reference: (summary, (image, alpha)) as two objects, so the
    driver reads the small summary and the pruned-set tasks get the images by reference."""
    _setup_worker(*setup)
    out = fn(task, scene=scene, ref=ref, keep_ref=True)
    return out, out.pop("ref_images", None)


def _ray_load_scene(setup, toolkit, path, lod):
    _setup_worker(*setup)
    return toolkit.load_scene(path, lod)


def _ray_probe(location: str, rel: str) -> tuple[str, bytes | None, str | None]:
    """(host, payload, problem) of the sealed probe at ``rel`` as this node sees it: unreadable,
    absent, or failing this node's checksum / cache key (``HARNESS_CACHE_KEY`` unset or different)."""
    import socket

    from harness.run.cache.entries import Sealer, cache_secret
    from harness.run.cache.stores import open_store

    host = socket.gethostname()
    try:
        store, _ = open_store(location)
        data = store.read(rel)
    except Exception as err:  # an unreachable location: report what the node saw
        return host, None, f"{type(err).__name__}: {err}"
    if data is None:
        return host, None, "nothing there"
    payload, problem = Sealer(cache_secret()).open_envelope(rel, data)
    return host, payload, problem


@dataclass
class _Job:
    stage: Stage
    task: Any
    scene_key: str | None  # digest of the scene it needs (None: it needs none)
    ref_key: str | None = None  # the view whose reference render it consumes
    provides_ref: bool = False  # it renders the view's reference and returns it
    refs: list = field(default_factory=list)  # its ObjectRefs once submitted


class RayExecutor(Executor):
    """Stages as Ray tasks on a local cluster (``address=None``: started here with ``workers × threads``
    CPUs and stopped at :meth:`close`) or on an existing cluster (``"auto"``, ``"HOST:PORT"``,
    ``"ray://HOST:10001"``). See the module text for scheduling, object passing and failures."""

    name = "ray"
    parallel = True

    def __init__(self, workers: int = 1, toolkit=None, *, address: str | None = None,
                 cpus_per_task: int | None = None, gpus_per_task: float = 1.0, max_retries: int = 2,
                 device: str = "cpu", cache_location: str | None = None, window: int | None = None,
                 log_to_driver: bool = True, log=print):
        from harness.run.toolkit import Toolkit

        self.workers = max(1, int(workers))
        self.toolkit = toolkit or Toolkit()
        self.address = address or None
        cores = os.cpu_count() or 1
        self.threads = int(cpus_per_task or (max(1, cores // self.workers) if self.address is None else 1))
        self.gpus_per_task = float(gpus_per_task)
        self.max_retries = int(max_retries)
        self.device = device
        self.cache_location = cache_location
        self.window = window
        self.log_to_driver = log_to_driver
        self.log = log
        self._ray = None
        self._owns = False  # this executor started the cluster (and stops it)
        self._temp_dir: str | None = None
        self._use_gpu = False

    # ------------------------------------------------------------------ cluster
    def describe(self) -> dict:
        d = {"name": self.name, "address": self.address or "local", "cpus_per_task": self.threads,
             "max_retries": self.max_retries, "gpu": self._use_gpu}
        if self._ray is not None and self._ray.is_initialized():
            res = self._ray.cluster_resources()
            d.update(cluster_cpus=res.get("CPU", 0), cluster_gpus=res.get("GPU", 0),
                     nodes=sum(1 for n in self._ray.nodes() if n.get("Alive")))
        if self.address is None:
            d["workers"] = self.workers
        return d

    def start(self):
        """Start or join the cluster (once); check that every node reaches the cache location."""
        if self._ray is not None:
            return self._ray
        try:
            import ray
        except ImportError:
            raise InputError(
                "--executor ray", "needs the ray package (pip install -e '.[ray]'; setup.sh installs it)"
            ) from None
        for k, v in QUIET_ENV.items():
            os.environ.setdefault(k, v)
        import sys

        if not sys.stderr.isatty():  # worker lines forwarded into a log file: no colour codes
            os.environ.setdefault("RAY_COLOR_PREFIX", "0")
        if ray.is_initialized():  # a caller (a test, a notebook) holds a cluster already: use it
            self._ray = ray
        else:
            kw = dict(logging_level=logging.WARNING, log_to_driver=self.log_to_driver)
            if self.address is None:
                for k, v in LOCAL_ENV.items():
                    os.environ.setdefault(k, v)
                # AF_UNIX socket paths (<temp>/session_<date>_<pid>/sockets/plasma_store) must stay
                # under 108 bytes: a short folder of our own, removed at close
                self._temp_dir = tempfile.mkdtemp(prefix="ray-", dir="/tmp")
                kw.update(address="local", num_cpus=self.workers * self.threads, include_dashboard=False,
                          _temp_dir=self._temp_dir)
            else:
                kw.update(address=self.address)
            try:
                ray.init(**kw)
            except Exception as err:  # noqa: BLE001 - ConnectionError, RuntimeError, TimeoutError ...
                raise InputError("--executor ray", f"Ray could not {'start' if self.address is None else 'join'} "
                                                   f"the cluster: {type(err).__name__}: "
                                                   f"{' '.join(str(err).split())[:200]}") from None
            self._owns = True
            self._ray = ray
            from harness.core.lifecycle import install_signal_handlers

            # ray.init replaced the SIGTERM handler; ours raises Terminated, and close() then stops
            # the cluster (a local one) from the run's `finally`
            install_signal_handlers()
        self._check_resources()
        # a private local cluster shares this machine's filesystem by construction; a cluster that
        # was joined may span nodes that do not see the cache: probe it from every node
        if self.cache_location is not None and (self.address is not None or not self._owns):
            self.check_cache(self.cache_location)
        return self._ray

    def _check_resources(self) -> None:
        res = self._ray.cluster_resources()
        if res.get("CPU", 0) < self.threads:
            raise InputError(
                "--executor ray", f"tasks ask for {self.threads} CPUs; the cluster has {res.get('CPU', 0):g}"
            )
        gpus = res.get("GPU", 0)
        if self.device.startswith("cuda"):
            if gpus <= 0:  # a task asking for a GPU on a CPU-only cluster would wait forever
                raise InputError("protocol.device", f"{self.device!r}, but the Ray cluster has no GPU "
                                                    f"(resources: {', '.join(sorted(res))})")
            self._use_gpu = True

    def check_cache(self, location: str) -> None:
        """Write a probe through the cache location here and read it on every node: a folder that is
        not shared (a node-local /tmp) or an unreachable URL fails now, not as missing entries later."""
        import uuid

        from harness.run.cache.entries import Sealer, cache_secret
        from harness.run.cache.stores import open_store

        ray = self._ray
        from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

        store, _ = open_store(location)
        rel = f".probe/{uuid.uuid4().hex}"
        token = uuid.uuid4().hex.encode()
        store.write(rel, Sealer(cache_secret()).envelope(rel, token))
        try:
            probe = ray.remote(_ray_probe)
            nodes = [n for n in ray.nodes() if n.get("Alive") and n.get("Resources", {}).get("CPU", 0) > 0]
            refs = [probe.options(num_cpus=0, max_retries=1, name="probe-cache", scheduling_strategy=
                                  NodeAffinitySchedulingStrategy(n["NodeID"], soft=False)).remote(location, rel)
                    for n in nodes]
            for n, (host, seen, problem) in zip(nodes, ray.get(refs, timeout=300)):
                if seen != token:
                    raise InputError(
                        location,
                        f"the stage cache is not usable from Ray node {host} "
                        f"({n.get('NodeManagerAddress')}): {problem or 'it read another probe'}; "
                        "give a folder every node mounts (NFS ...) or an fsspec URL "
                        "(s3://bucket/prefix), and the same HARNESS_CACHE_KEY on every node",
                    )
        finally:
            store.delete(rel)

    def close(self) -> None:
        if self._ray is not None and self._owns:
            try:
                self._ray.shutdown()
            finally:
                self._owns = False
                if self._temp_dir:
                    shutil.rmtree(self._temp_dir, ignore_errors=True)
                    self._temp_dir = None
        self._ray = None

    # ------------------------------------------------------------------ work
    def _jobs(self, stages: Sequence[Stage]) -> list[_Job]:
        """All tasks, grouped by scene then view in order of first appearance (a view's reference
        task before its pruned sets), so a scene's and a view's objects are needed for a short while."""
        jobs = []
        for s in stages:
            for t in s.tasks:
                provides = s.fn is run_view and getattr(t, "render_ref", False)
                jobs.append(_Job(s, t, getattr(t, "scene_digest", None),
                                 getattr(t, "ref_key", None) if s.fn is run_view else None, provides))
        first_scene: dict = {}
        first_view: dict = {}
        for i, j in enumerate(jobs):
            first_scene.setdefault(j.scene_key, i)
            first_view.setdefault((j.scene_key, j.ref_key), i)
        order = sorted(range(len(jobs)), key=lambda i: (first_scene[jobs[i].scene_key],
                                                        first_view[(jobs[i].scene_key, jobs[i].ref_key)], i))
        return [jobs[i] for i in order]

    def options(self, job: _Job) -> dict:
        """Resources of a task: CPUs always; a GPU share for the tasks that compute on the device
        (``stage.on_device``: renders/metrics, scores of pruners that declare ``uses_device``) when
        the run's device is CUDA (the other pruners are numpy/numba: CPU only)."""
        o = {"num_cpus": self.threads, "max_retries": self.max_retries, "retry_exceptions": False,
             "name": f"{job.stage.name}[{getattr(job.task, 'label', '') or '?'}]"}
        if self._use_gpu and job.stage.on_device(job.task):
            o["num_gpus"] = self.gpus_per_task
        return o

    def run(self, stages: Sequence[Stage], bars: Bars) -> list[list[dict]]:
        """Every task of ``stages``, at most a window of them in flight (twice the task slots), in
        :meth:`_jobs` order; results per stage, bars advanced as each ends. Ctrl-C, SIGTERM or a bug
        cancels what is in flight."""
        results: list[list[dict]] = [[] for _ in stages]
        if not any(s.tasks for s in stages):
            return results
        ray = self.start()
        index = {id(s): i for i, s in enumerate(stages)}
        _start_bars(stages, bars)
        jobs = self._jobs(stages)
        pipe = _Pipeline(ray, self, jobs)
        window = self.window or max(4, 2 * int(ray.cluster_resources().get("CPU", 1) // self.threads))
        pending: dict = {}  # summary ObjectRef -> job
        queue = list(reversed(jobs))
        try:
            while queue or pending:
                while queue and len(pending) < window:
                    j = queue.pop()
                    pending[pipe.submit(j)] = j
                ready, _ = ray.wait(list(pending), num_returns=1, timeout=1.0)
                for r in ready:
                    j = pending.pop(r)
                    results[index[id(j.stage)]].append(self._result(ray, r, j))
                    bars.advance(j.stage.name, j.stage.weight(j.task))
        except BaseException:  # Ctrl-C / SIGTERM / a bug here: nothing keeps running for this run
            _cancel(ray, pending)
            raise
        for s in (s for s in stages if s.tasks):
            bars.finish(s.name)
        return results

    def _result(self, ray, ref, job: _Job) -> dict:
        from ray.exceptions import RayTaskError, TaskCancelledError

        what = f"{job.stage.name} {getattr(job.task, 'label', '') or ''}".strip()
        try:
            return ray.get(ref)
        except RayTaskError as err:  # an exception escaped the stage function (or the scene load): not retried
            cause = getattr(err, "cause", None) or err
            if isinstance(cause, StorageFull):  # a full disk on a node: the run's end, as on one machine
                raise cause from None
            first = _ANSI.sub("", str(cause)).strip().splitlines()
            return job.task.failed(f"{what}: {type(cause).__name__}: {first[-1] if first else ''}")
        except TaskCancelledError:
            return job.task.failed(f"{what}: cancelled")
        except ray.exceptions.LocalRayletDiedError:  # no task can run any more: stop the run, say why
            raise InputError("--executor ray", "the Ray cluster stopped during the run: the raylet of this node "
                                               "died (killed, out of memory, or its runtime-env agent died); what "
                                               "was computed is in the stage cache, a rerun resumes there") from None
        except ray.exceptions.RayError as err:  # the worker (or its node) died on every attempt
            first = _ANSI.sub("", str(err)).strip().splitlines()
            return job.task.failed(f"{what}: the worker died {self.max_retries + 1} times running it (killed, out "
                                   f"of memory or crashed): {type(err).__name__}: {first[0] if first else ''}")


def _start_bars(stages: Sequence[Stage], bars: Bars) -> None:
    """A bar per stage with tasks, its total the tasks' weight."""
    for s in stages:
        if s.tasks:
            bars.start(s.name, sum(s.weight(t) for t in s.tasks))


def _cancel(ray, pending) -> None:
    for r in pending:
        try:
            ray.cancel(r, force=True)
        except Exception:  # noqa: BLE001 - a task that ended meanwhile
            pass


class _Pipeline:
    """Submits jobs with their inputs by reference: a scene is loaded once, by one task, into the
    object store for every job of that scene; a view's reference render, returned by the job that
    renders it, goes to the jobs that measure the view's pruned sets. The driver drops its handle
    of a scene or view once its last consumer is submitted (submitted tasks keep it alive)."""

    def __init__(self, ray, executor: RayExecutor, jobs: list[_Job]):
        self.ray, self.ex = ray, executor
        self.setup = (executor.threads, tuple(executor.toolkit.imports), tuple(executor.toolkit.preload))
        self.call = ray.remote(_ray_call)
        self.call_keep = ray.remote(num_returns=2)(_ray_call_keep_ref)
        self.load = ray.remote(_ray_load_scene)
        self.scenes: dict = {}  # scene digest -> ObjectRef of the loaded scene
        self.views: dict = {}  # ref key -> ObjectRef of (image, alpha) rendered in this call
        self.left_scene: dict = {}  # consumers left to submit per scene / per view
        self.left_view: dict = {}
        for j in jobs:
            self.left_scene[j.scene_key] = self.left_scene.get(j.scene_key, 0) + 1
            if j.ref_key is not None and not j.provides_ref:
                self.left_view[j.ref_key] = self.left_view.get(j.ref_key, 0) + 1

    def _scene(self, j: _Job):
        if j.scene_key is None:
            return None
        ref = self.scenes.get(j.scene_key)
        if ref is None:
            t = j.task
            ref = self.scenes[j.scene_key] = self.load.options(
                num_cpus=1, max_retries=self.ex.max_retries, retry_exceptions=False,
                name=f"load[{getattr(t, 'label', '') or t.path}]").remote(self.setup, t.toolkit, t.path, t.lod)
        self.left_scene[j.scene_key] -= 1
        if not self.left_scene[j.scene_key]:
            del self.scenes[j.scene_key]
        return ref

    def _view(self, j: _Job):
        if j.ref_key is None or j.provides_ref:
            return None
        ref = self.views.get(j.ref_key)
        self.left_view[j.ref_key] -= 1
        if not self.left_view[j.ref_key]:
            self.views.pop(j.ref_key, None)
        return ref

    def submit(self, j: _Job):
        """Submit ``j``; the ObjectRef of its summary."""
        scene, view = self._scene(j), self._view(j)
        opts = self.ex.options(j)
        if not j.provides_ref:
            return self.call.options(**opts).remote(j.stage.fn, self.setup, j.task, scene, view)
        summary, images = self.call_keep.options(**opts).remote(j.stage.fn, self.setup, j.task, scene, None)
        if self.left_view.get(j.ref_key):
            self.views[j.ref_key] = images
        return summary
