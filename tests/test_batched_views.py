"""A view's pruned sets measured in batches with the metrics' torch forms (what a study on CUDA
does) give the CPU forms' values, image by image: a whole run on CPU torch, in-process."""

from __future__ import annotations

import numpy as np
import pytest

from harness.report.results import to_frame
from harness.run.config import parse_config
from harness.run.runner import Runner
from tests import runner_fakes as fakes

METRICS = ["psnr", "ssim", "rgb_psnr", "yuv_psnr", "yuv_ssim", "rgb_psnr_om", "yuv_ssim_om", "yuv_ivssim"]


def batched_metrics(names, device):
    """The suite a CUDA study makes (torch forms, several images per call), on the CPU."""
    from harness.metrics.suite import MetricSuite

    return MetricSuite(names=names, device=device, max_in_memory=1, torch_forms=True, batch=3)


def _run(tmp_path, name, scenes, **toolkit):
    cfg = parse_config({"name": "t", "protocol": {"longest_side": 40, "metrics": METRICS, "n_train": 3, "n_test": 2},
                        "ratios": [0.1, 0.2, 0.3, 0.5], "scenes": [{"name": k, "source": v} for k, v in scenes.items()],
                        "methods": ["opacity", "random", "fake-norm"]}, "test.yaml")
    res = Runner(cfg, out_dir=tmp_path / name, cache_root=tmp_path / f"cache-{name}", toolkit=fakes.toolkit(**toolkit),
                 log=lambda m: None).run()
    df = to_frame(res.rows).sort_values(["scene", "method", "ratio", "view"]).reset_index(drop=True)
    return res, df


def test_batched_torch_forms_equal_the_image_by_image_cpu_forms(tmp_path):
    scenes = fakes.write_two_scenes(tmp_path)
    cpu_res, cpu = _run(tmp_path, "cpu", scenes)
    res, dev = _run(tmp_path, "batched", scenes, make_metrics=batched_metrics)
    assert not cpu_res.errors and not res.errors
    assert len(dev) == len(cpu) == 2 * 3 * 4 * 2 and (dev["status"] == "ok").all()
    for m in METRICS + ["occupancy"]:
        assert np.allclose(dev[m].to_numpy(float), cpu[m].to_numpy(float), rtol=0, atol=1e-12, equal_nan=True), m
    tool_psnrs = ["rgb_psnr", "yuv_psnr", "rgb_psnr_om"]  # the MPEG tool's PSNRs: bit for bit
    assert (dev[tool_psnrs] == cpu[tool_psnrs]).all().all()
    # every entry records its share of its batch's scoring
    assert (dev["metrics_s"] > 0).all()


def test_a_failing_set_fails_alone_and_a_failing_batch_fails_its_sets(tmp_path):
    from harness.run import tasks

    class Suite:
        def __init__(self, fail):
            self.fail = fail

        def score_many(self, key, images, alphas=None):
            if self.fail:
                raise ValueError("scoring broke")
            return [{"psnr": 30.0} for _ in images]

    class Cache:
        def __init__(self):
            self.stored = []

        def get_array(self, stage, key, count=False, check=None):
            return None if key == "gone" else np.packbits(np.ones(4, bool))

        def put_json(self, stage, key, rec):
            self.stored.append(key)

    class Renders:
        pack_s = 0.0

        def __call__(self, keep):
            return np.zeros((2, 2, 3), np.float32), None

    task = tasks.ViewTask("c", "ref", "p", None, "d", 4, {}, "gl", "cpu", (0, 0, 0), ("psnr",), [])
    jobs = [tasks.MaskJob("m1", "k1"), tasks.MaskJob("m2", "gone"), tasks.MaskJob("m3", "k3")]
    cache = Cache()
    out = tasks._measure_sets(task, cache, Suite(False), Renders(), jobs, 0.0, False)
    assert [(j.metrics_key, e is None) for j, e in out] == [("m1", True), ("m2", False), ("m3", True)]
    assert "missing" in out[1][1] and cache.stored == ["m1", "m3"]
    out = tasks._measure_sets(task, Cache(), Suite(True), Renders(), jobs, 0.0, False)
    assert [e for _, e in out] == ["ValueError: scoring broke", out[1][1], "ValueError: scoring broke"]


@pytest.mark.parametrize("names", [("psnr",), ("psnr", "ssim", "rgb_psnr")])
def test_batch_size_is_one_on_the_cpu_forms(names):
    from harness.metrics.suite import MetricSuite

    assert MetricSuite(names=names, device="cpu").batch_size(768, 1024) == 1
    assert MetricSuite(names=names, device="cpu", batch=5).batch_size(768, 1024) == 5
