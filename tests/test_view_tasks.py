"""The study's view tasks: a view's reference features and projection are computed once for all its
pruned sets, and views are split only when there are too few to keep the workers busy."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from harness.report.results import to_frame
from harness.run.config import parse_config
from harness.run.runner import MIN_CHUNK, Runner, view_parts
from tests import runner_fakes as fakes

CALLS: Counter = Counter()


@pytest.mark.parametrize("n, views, slots, sizes", [
    (23, 80, 8, [23]),            # the default study on 2 workers: one task per view
    (23, 1, 8, [11, 12]),         # one view: split, but never below MIN_CHUNK sets per task
    (25, 1, 8, [8, 8, 9]),
    (100, 2, 8, [25, 25, 25, 25]),
    (5, 1, 8, [5]),               # too few sets to be worth a second reference pass
    (40, 3, 1, [40]),             # in-process: never split
])
def test_view_parts(n, views, slots, sizes):
    parts = view_parts(list(range(n)), views, slots)
    assert [len(p) for p in parts] == sizes
    assert sum(parts, []) == list(range(n))
    assert len(parts) == 1 or min(sizes) >= MIN_CHUNK


class _Packed:
    def __init__(self, scene, camera):
        self.scene, self.camera = scene, camera

    def kept(self, keep):
        return _Packed(self.scene.subset(keep), self.camera)


class PackingPointRenderer(fakes.PointRenderer):
    """The fake point renderer with the GL renderer's pack/draw protocol, counting packs."""

    capabilities = frozenset({"pack"})

    def pack(self, scene, camera):
        CALLS["pack"] += 1
        return _Packed(scene, camera)

    def draw(self, view, background=(0.0, 0.0, 0.0), with_alpha=False):
        img = self.render(view.scene, view.camera, background)
        return (img, np.ones(img.shape[:2], np.float32)) if with_alpha else img


def make_packing_renderer(name, device):
    return PackingPointRenderer()


class CountingSuite:
    """The real metric suite, counting the references it registers."""

    def __init__(self, names, device):
        from harness.metrics.suite import MetricSuite

        self.suite = MetricSuite(names=names, device=device, max_in_memory=1)

    def reference(self, key, image, alpha=None):
        CALLS["reference"] += 1
        return self.suite.reference(key, image, alpha=alpha)

    def score_many(self, key, images, alphas=None):
        return self.suite.score_many(key, images, alphas)

    def batch_size(self, height, width):
        return self.suite.batch_size(height, width)


def make_counting_metrics(names, device):
    return CountingSuite(names, device)


def _run(tmp_path, toolkit, name):
    scene = fakes.write_two_scenes(tmp_path)["s1"]
    ratios = [round(0.05 * k, 2) for k in range(1, 12)]  # 11 pruned sets per view: more than MIN_CHUNK
    cfg = parse_config({"name": "t", "protocol": {"longest_side": 32, "metrics": ["psnr", "ssim"], "n_train": 3,
                                                   "n_test": 3}, "ratios": ratios,
                        "scenes": [{"name": "s1", "source": scene}], "methods": ["fake-norm"]}, "t.yaml")
    runner = Runner(cfg, out_dir=tmp_path / name, cache_root=tmp_path / f"cache-{name}", toolkit=toolkit,
                    log=lambda m: None)
    return to_frame(runner.run().rows)


def test_reference_features_and_projection_once_per_view(tmp_path):
    CALLS.clear()
    df = _run(
        tmp_path, fakes.toolkit(make_renderer=make_packing_renderer, make_metrics=make_counting_metrics), "packed"
    )
    assert len(df) == 3 * 11 and (df["status"] == "ok").all()
    assert CALLS["reference"] == 3  # one per view, not one per chunk of sets
    assert CALLS["pack"] == 3 + 3  # the reference render's task and the pruned sets' task of each view
    plain = _run(tmp_path, fakes.toolkit(), "plain")  # renders every pruned scene
    cols = ["ratio", "view", "psnr", "ssim"]
    assert df[cols].sort_values(cols[:2]).reset_index(drop=True).equals(
        plain[cols].sort_values(cols[:2]).reset_index(drop=True))
