"""``executor:`` of a run config: where the work units run (:mod:`harness.run.executors`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from harness.core.errors import InputError
from harness.run.config_checks import choice, expand_env, mapping, num, only, string

EXECUTORS = ("local", "ray")


@dataclass(frozen=True)
class ExecutorSpec:
    """Where the work units run (:mod:`harness.run.executors`)."""

    name: str = "local"
    address: str | None = None  # ray: None = start a local cluster; "auto", "HOST:PORT", "ray://HOST:10001"
    cpus_per_task: int | None = None  # ray: CPUs (= threads) per task; default cores // workers locally, 1 on a cluster
    gpus_per_task: float = 1.0  # ray: GPU share of a render/metrics/camera-aware task when protocol.device is CUDA
    max_retries: int = 2  # ray: re-runs of a task whose worker process died (never of a task that raised)


def parse_executor(v, src) -> ExecutorSpec:
    """``executor: local|ray`` or a mapping ``{name: ray, address: ..., cpus_per_task: ..., ...}``."""
    if v is None:
        return ExecutorSpec()
    if isinstance(v, str):
        v = {"name": v}
    d = mapping(v, "executor", src)
    only(d, set(ExecutorSpec.__dataclass_fields__), "executor", src)
    name = choice(d.get("name", "local"), EXECUTORS, "executor.name", src)
    if name == "local" and set(d) - {"name"}:
        raise InputError(src, f"executor: {', '.join(sorted(set(d) - {'name'}))} go with `name: ray`")
    kw: dict[str, Any] = {"name": name}
    if d.get("address") is not None:
        kw["address"] = expand_env(string(d["address"], "executor.address", src))
    if d.get("cpus_per_task") is not None:
        kw["cpus_per_task"] = num(d["cpus_per_task"], "executor.cpus_per_task", src, lo=1, hi=1024, integer=True)
    if "gpus_per_task" in d:
        kw["gpus_per_task"] = float(num(d["gpus_per_task"], "executor.gpus_per_task", src, lo=0.01, hi=64))
    if "max_retries" in d:
        kw["max_retries"] = num(d["max_retries"], "executor.max_retries", src, lo=0, hi=100, integer=True)
    return ExecutorSpec(**kw)
