"""How many device workers a local GPU run gets (decided without opening the device), and a whole
run routed as on a GPU (device tasks to the device worker) giving the CPU run's rows."""

from __future__ import annotations

import pytest

from harness.report.results import to_frame
from harness.run.config import parse_config
from harness.run.executors import device as dev
from harness.run.runner import Runner
from tests import runner_fakes as fakes

GIB = 1 << 30


@pytest.mark.parametrize("name, expected", [("cpu", False), ("CPU", False), ("cuda", True), ("cuda:1", True),
                                            ("mps", True), ("", False), (None, False)])
def test_is_device(name, expected):
    assert dev.is_device(name) is expected


@pytest.mark.parametrize("device, workers, asked, free, expected", [
    ("cpu", 8, 0, 100 * GIB, 0),  # a CPU run: one pool
    ("cuda", 1, 0, 100 * GIB, 0),  # one worker computes in-process
    ("cuda", 8, 3, 1 * GIB, 3),  # asked for: given
    ("cuda", 8, 0, 139 * GIB, dev.MOST_AUTO),  # a large device: a few, not one per worker
    ("cuda", 2, 0, 139 * GIB, 2),  # never more than the workers
    ("cuda", 8, 0, 30 * GIB, 30 // dev.GIB_PER_WORKER),
    ("cuda", 8, 0, 4 * GIB, 1),  # at least one
])
def test_device_worker_count(device, workers, asked, free, expected):
    assert dev.device_worker_count(device, workers, asked, free=free) == expected


def test_without_nvidia_smi_one_device_worker(monkeypatch):
    monkeypatch.setattr(dev.shutil, "which", lambda name: None)
    assert dev.free_bytes("cuda") is None
    assert dev.device_worker_count("cuda", 8) == 1


def test_the_nvml_index_follows_cuda_visible_devices(monkeypatch):
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "2,GPU-1234")
    assert dev._nvml_index("cuda") == "2" and dev._nvml_index("cuda:1") == "GPU-1234"
    monkeypatch.delenv("CUDA_VISIBLE_DEVICES")
    assert dev._nvml_index("cuda:3") == "3"


def test_a_device_run_routes_its_device_tasks_and_gives_the_cpu_runs_rows(tmp_path):
    scenes = fakes.write_two_scenes(tmp_path)

    def run(name, device, workers):
        cfg = parse_config({"name": "t", "protocol": {"longest_side": 32, "metrics": ["psnr", "ssim"], "n_train": 3,
                                                      "n_test": 2, "device": device},
                            "executor": {"name": "local", "device_workers": 1}, "ratios": [0.1, 0.3],
                            "scenes": [{"name": k, "source": v} for k, v in scenes.items()],
                            "methods": ["fake-norm", "fake-device"]}, "test.yaml")
        res = Runner(cfg, out_dir=tmp_path / name, cache_root=tmp_path / f"cache-{name}", workers=workers,
                     toolkit=fakes.toolkit(make_metrics=fakes.cpu_metrics), log=lambda m: None).run()
        assert not res.errors
        cols = ["scene", "method", "ratio", "view", "status", "psnr", "ssim", "splats_out", "tau"]
        return res, to_frame(res.rows)[cols].sort_values(cols[:4]).reset_index(drop=True)

    cpu_res, cpu = run("cpu", "cpu", 1)
    gpu_res, gpu = run("gpu", "cuda", 2)
    assert "tasks" not in cpu_res.executor
    assert gpu_res.executor["device_workers"] == 1
    tasks = gpu_res.executor["tasks"]
    assert tasks["score"] == {"cpu": 2, "device": 2}  # fake-norm on the CPU workers, fake-device on the device's
    assert tasks["render_ref"]["cpu"] == tasks["render+metrics"]["cpu"] == 0
    assert tasks["render_ref"]["device"] == tasks["render+metrics"]["device"] == 4  # 2 scenes x 2 views
    assert len(gpu) == 16 and gpu.equals(cpu)


def test_the_gpu_benchmark_reports_where_the_tasks_ran():
    from harness.benchmarks._study_device import _device_workers

    assert _device_workers({"name": "local", "workers": 8, "threads": 2}) == []  # a CPU run: no row
    row = _device_workers({"device_workers": 2, "tasks": {"score": {"cpu": 30, "device": 10},
                                                          "render+metrics": {"cpu": 0, "device": 40}}})
    assert row == ["| device workers (tasks per stage) | 2 (score 30 CPU / 10 device; render+metrics 0 CPU / 40 "
                   "device) |"]
