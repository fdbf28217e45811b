"""``executor:`` of a run config: where the work units run (:mod:`harness.run.executors`)."""

from __future__ import annotations

from dataclasses import dataclass

from harness.core.errors import InputError
from harness.run.config.checks import expand_env, mapping, string
from harness.run.config.schema import config_param, read_section

EXECUTORS = ("local", "ray")


def _address(v, key, src):
    return None if v is None else expand_env(string(v, key, src))


@dataclass(frozen=True)
class ExecutorSpec:
    """Where the work units run (:mod:`harness.run.executors`)."""

    name: str = config_param("local", changes=(), choices=EXECUTORS, doc="local (a process pool) or ray")
    address: str | None = config_param(None, parse=_address, changes=(),
                                       doc="ray: none = start a local cluster; auto, HOST:PORT or ray://HOST:10001")
    cpus_per_task: int | None = config_param(
        None, ge=1, le=1024, changes=(),
        doc="ray: CPUs (= threads) per task; default cores // workers locally, 1 on a cluster")
    gpus_per_task: float = config_param(
        1.0, ge=0.01, le=64, changes=(),
        doc="ray: GPU share of a task that computes on the device (renders, metrics, uses_device pruners) "
            "when protocol.device is CUDA"
    )
    max_retries: int = config_param(
        2, ge=0, le=100, changes=(),
        doc="ray: re-runs of a task whose worker process died (never of a task that raised)")
    device_workers: int = config_param(
        0, ge=0, le=64, changes=(),
        doc="local, protocol.device CUDA: worker processes that run the device's tasks beside the CPU workers "
            "(0: one per 12 GiB of free device memory, 1 to 4)")


#: keys of ``executor:`` that only the Ray executor reads
RAY_KEYS = frozenset({"address", "cpus_per_task", "gpus_per_task", "max_retries"})


def parse_executor(v, src) -> ExecutorSpec:
    """``executor: local|ray`` or a mapping ``{name: ray, address: ..., cpus_per_task: ..., ...}``
    (``{name: local, device_workers: k}`` for a GPU run on the local pool)."""
    if v is None:
        return ExecutorSpec()
    if isinstance(v, str):
        v = {"name": v}
    d = mapping(v, "executor", src)
    if d.get("name", "local") == "local" and set(d) & RAY_KEYS:
        raise InputError(src, f"executor: {', '.join(sorted(set(d) & RAY_KEYS, key=str))} go with `name: ray`")
    if d.get("name") == "ray" and "device_workers" in d:
        raise InputError(src, "executor: device_workers goes with the local executor (Ray shares the GPU by "
                              "gpus_per_task)")
    return ExecutorSpec(**read_section(ExecutorSpec, d, "executor", src))
