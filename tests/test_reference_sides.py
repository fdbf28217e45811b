"""A reference's side of SSIM and of the MPEG set, computed once per view, gives the values of
scoring every pair from scratch, bit for bit (the independent truth: the from-scratch functions)."""

from __future__ import annotations

import numpy as np
import pytest
from skimage import data

from harness.metrics import mpeg
from harness.metrics.registry import expand
from harness.metrics.ssim import SsimReference, ssim_batch
from harness.metrics.suite import MetricSuite, compare_images


def _images(seed: int, h: int = 37, w: int = 52):
    rng = np.random.default_rng(seed)
    ref = data.astronaut()[:h * 3:3, :w * 3:3].astype(np.float32) / 255
    tests = [np.clip(ref + rng.normal(0, s, ref.shape), -0.1, 1.1).astype(np.float32) for s in (0.003, 0.02, 0.2)]
    tests.append(ref.copy())
    alphas = [rng.random((h, w), dtype=np.float32) for _ in range(len(tests) + 1)]
    return ref, tests, alphas


@pytest.mark.parametrize("qmiv, rounding, top_down", [(False, "float32", True), (True, "float32", True),
                                                      (False, "gcc-o3", True), (False, "float32", False)])
def test_tool_reference_reused_equals_fresh(qmiv, rounding, top_down):
    ref, tests, alphas = _images(1)
    prep = mpeg.ToolReference(ref, qmiv=qmiv, rows_top_down=top_down, yuv_rounding=rounding)
    for img, alpha in zip(tests, alphas[1:]):
        for mask in (None, mpeg.occupancy_mask(alphas[0], alpha)):
            kw = dict(qmiv=qmiv, rows_top_down=top_down, yuv_rounding=rounding)
            assert mpeg.tool_metrics(prep, img, mask, **kw) == mpeg.tool_metrics(ref, img, mask, **kw)
    with pytest.raises(ValueError, match="sizes differ"):
        mpeg.tool_metrics(prep, tests[0][:-1])


def test_ssim_reference_reused_equals_fresh():
    ref, tests, _ = _images(2)
    prep = SsimReference(ref[None], device="cpu")
    for border in ("zero", "valid"):
        for img in tests:
            assert ssim_batch(prep, img[None], border=border) == ssim_batch(
                ref[None], img[None], border=border, device="cpu"
            )


def test_suite_scores_equal_pairs_scored_from_scratch():
    names = tuple(n for n in expand(["3dgs", "mpeg", "mpeg-qmiv"]) if n != "lpips")
    ref, tests, alphas = _images(3, 40, 48)
    suite = MetricSuite(names=names, device="cpu", max_in_memory=1)
    suite.reference("view", ref, alpha=alphas[0])
    for img, alpha in zip(tests, alphas[1:]):
        got = suite.score("view", img, alpha=alpha)
        want = compare_images(ref, img, names=names, mask=mpeg.occupancy_mask(alphas[0], alpha))
        assert got == want
    suite.reference("other", tests[1], alpha=alphas[0])  # evicts "view" (one view in memory)
    assert suite.score("other", ref, alpha=alphas[1]) == compare_images(
        tests[1], ref, names=names, mask=mpeg.occupancy_mask(alphas[0], alphas[1]))
