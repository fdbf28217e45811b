"""The metrics' torch forms (harness.metrics.batched, mpeg_torch, mpeg_ssim_torch, ivssim_torch) against
the CPU forms they must equal: run here on CPU torch, and on CUDA where a GPU is present. PSNRs of the
MPEG set bit for bit (==), every other value to 1e-12; per-pixel SSIM moments, the padding, the global
colour shift and the shift-compensated pictures bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from harness.core.errors import InputError
from harness.metrics import ivssim, ivssim_torch, mpeg, mpeg_ssim, mpeg_ssim_torch, mpeg_torch
from harness.metrics import lpips_weights as lw
from harness.metrics.registry import expand
from harness.metrics.suite import METRICS, MetricSuite

TOL = 1e-12
#: values the torch forms reduce in parallel (the tool adds them in sequence): equal to TOL, not bit for bit
REDUCED = ("ssim_yuv", "yuv_ssim", "ssim_yuv_om", "yuv_ssim_om", "rgb_ivssim", "yuv_ivssim")
NO_CUDA = "no CUDA device here: the torch forms' GPU run is checked on a GPU machine (scripts/gpu_study.sh)"
DEVICES = ["cpu", pytest.param("cuda", marks=pytest.mark.skipif(not torch.cuda.is_available(), reason=NO_CUDA))]


def _renders(h, w, seed, n=3):
    """A smooth float reference, n noisy or shifted renders of it (the last identical), and alphas."""
    rng = np.random.default_rng(seed)
    ref = np.cumsum(np.cumsum(rng.random((h, w, 3)), 0), 1)
    ref = (ref / ref.max() * 1.1 - 0.05).astype(np.float32)  # a little outside [0, 1]: clamped
    imgs = [np.clip(ref + rng.normal(0, s, ref.shape), -0.1, 1.1).astype(np.float32) for s in (0.004, 0.03)]
    imgs = (imgs + [np.roll(ref, 1, axis=1) + np.float32(2 / 255), ref.copy()])[:n]
    alphas = [rng.random((h, w)).astype(np.float32) for _ in imgs]
    alphas[-1][:] = 0.0
    return ref, imgs, rng.random((h, w)).astype(np.float32), alphas


def _equal(got, want, key):
    g, w = np.asarray(got, float), np.asarray(want, float)
    if key in REDUCED:
        assert np.allclose(g, w, rtol=0, atol=TOL, equal_nan=True), (key, got, want)
    else:
        assert np.array_equal(g, w, equal_nan=True), (key, got, want)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("qmiv", [False, True])
@pytest.mark.parametrize("shape", [(5, 3), (9, 7), (37, 23), (48, 64)])
def test_tool_metrics_batch_equals_the_tool(shape, qmiv, device):
    ref, imgs, alpha, alphas = _renders(*shape, seed=shape[0], n=4)
    prep = mpeg_torch.ToolReferenceT(torch.from_numpy(ref), qmiv=qmiv, device=device)
    cpu = mpeg.ToolReference(ref, qmiv=qmiv)
    masks = np.stack([mpeg.occupancy_mask(alpha, a) for a in alphas])
    for m in (None, masks):
        rows = mpeg_torch.tool_metrics_batch(prep, torch.from_numpy(np.stack(imgs)), m)
        for k, row in enumerate(rows):
            want = mpeg.tool_metrics(cpu, imgs[k], None if m is None else m[k])
            assert set(row) == set(want)
            for key in want:
                _equal(row[key], want[key], key)


def test_uint8_pictures_and_the_quantisation_edges():
    vals = np.array([0.5 / 255, 1.5 / 255, 2.5 / 255, -0.2, 1.7, 254.5 / 255, np.nan, 0.49999997 / 255], np.float32)
    img = np.repeat(vals[None, :, None], 3, axis=2)
    assert np.array_equal(mpeg_torch.quantize(torch.from_numpy(img)).numpy(), mpeg.quantize(img))
    rng = np.random.default_rng(1)
    a, b = (rng.integers(0, 256, (12, 10, 3)).astype(np.uint8) for _ in range(2))
    row = mpeg_torch.tool_metrics_batch(mpeg_torch.ToolReferenceT(torch.from_numpy(a)), torch.from_numpy(b[None]))[0]
    want = mpeg.tool_metrics(a, b)
    assert row["rgb_psnr"] == want["rgb_psnr"] and row["yuv_psnr"] == want["yuv_psnr"]


def test_identical_images_hit_the_caps():
    ref, _, _, _ = _renders(16, 16, 2)
    prep = mpeg_torch.ToolReferenceT(torch.from_numpy(ref))
    row = mpeg_torch.tool_metrics_batch(prep, torch.from_numpy(ref[None]))[0]
    assert row["rgb_psnr"] == row["yuv_psnr"] == mpeg.CAP and row["yuv_ssim"] == 1.0 and row["rgb_ivssim"] == 1.0


@pytest.mark.parametrize("shape", [(1, 3), (3, 4), (4, 9), (20, 30)])
def test_padding_and_moments_bit_equal(shape):
    rng = np.random.default_rng(shape[1])
    plane = rng.integers(0, 256, shape).astype(np.float64) + rng.random(shape)
    padded = mpeg_ssim_torch.pad(torch.from_numpy(plane))
    assert np.array_equal(padded.numpy(), mpeg_ssim.pad_like_tool(plane))
    stats = mpeg_ssim_torch.plane_stats(torch.from_numpy(plane)[None, None])
    want = mpeg_ssim.plane_stats(plane).complete()
    assert np.array_equal(stats.mu[0, 0].numpy(), want.mu) and np.array_equal(stats.var[0, 0].numpy(), want.var)


@pytest.mark.parametrize("weights", [ivssim.EQUAL_WEIGHTS, ivssim.DEFAULT_WEIGHTS])
def test_ivssim_steps_bit_equal(weights):
    rng = np.random.default_rng(4)
    a = rng.integers(0, 256, (21, 26, 3)).astype(np.int32)
    b = np.clip(np.roll(a, 1, 0) + rng.integers(-6, 7, a.shape) + 2, 0, 255).astype(np.int32)
    ta, tb = (torch.from_numpy(x).permute(2, 0, 1)[None] for x in (a, b))
    g = ivssim_torch.global_colour_shift(ta, tb)
    assert g[0].tolist() == ivssim.global_colour_shift(a, b).tolist()
    moved = ivssim_torch.shift_compensate(tb, ta, g, weights)[0].permute(1, 2, 0).numpy()
    planar = [np.ascontiguousarray(np.moveaxis(x, 2, 0)) for x in (b, a)]
    assert np.array_equal(moved, np.moveaxis(ivssim._shifted(*planar, g[0].numpy(), weights), 0, 2))
    got = ivssim_torch.iv_ssim_batch(torch.from_numpy(a)[None], torch.from_numpy(np.stack([b, a])), weights)
    assert abs(float(got[0]) - ivssim.iv_ssim_planes(a, b, weights)) <= TOL and float(got[1]) == 1.0
    small = ivssim_torch.iv_ssim_batch(ta.permute(0, 2, 3, 1)[:, :7], tb.permute(0, 2, 3, 1)[:, :7], weights)
    assert torch.isnan(small).all()


def _names(with_lpips: bool) -> tuple[str, ...]:
    return tuple(n for n in METRICS if with_lpips or n != "lpips")


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("photo", [False, True])
def test_suite_torch_forms_equal_the_cpu_forms(device, photo):
    """Every metric of a view, its OM variants from both renders' alphas and the photo metrics: the
    batched torch forms against the suite's CPU forms, image by image."""
    names = _names(lw.weights_available())
    ref, imgs, alpha, alphas = _renders(40, 56, 7, n=4)
    shot = np.clip(ref[::-1, :, ::-1] * 0.9 + 0.05, 0, 1).copy() if photo else None
    rows = {}
    for forms, dev in ((False, "cpu"), (True, device)):
        suite = MetricSuite(names=names, device=dev, torch_forms=forms)
        suite.reference("v", ref, alpha=alpha, photo=shot)
        rows[forms] = suite.score_many("v", imgs, alphas)
    for cpu, dev in zip(rows[False], rows[True]):
        assert set(cpu) == set(dev)
        for k in cpu:
            assert cpu[k] == pytest.approx(dev[k], rel=0, abs=2e-6 if k.endswith("lpips") else TOL), k


def test_suite_batches_and_checks_its_input():
    suite = MetricSuite(names=("psnr", "rgb_psnr"), device="cpu", torch_forms=True)
    assert suite.batch_size(768, 1024) == 1  # off CUDA: one image per call
    ref, imgs, _, _ = _renders(20, 24, 3)
    suite.reference("v", ref)
    as_tensor = suite.score_many("v", torch.from_numpy(np.stack(imgs)))
    assert as_tensor == suite.score_many("v", imgs)
    with pytest.raises(InputError, match="not \\(N, 20, 24, 3\\)"):
        suite.score_many("v", torch.zeros((1, 20, 25, 3)))
    bad = torch.from_numpy(np.stack(imgs)).clone()
    bad[0, 3, 4, 1] = float("nan")
    with pytest.raises(InputError, match="NaN"):
        suite.score_many("v", bad)
    with pytest.raises(InputError, match="image sizes differ"):
        suite.score_many("v", [np.zeros((20, 25, 3), np.float32)])


def test_a_metric_without_a_torch_form_runs_its_cpu_form(monkeypatch):
    """A plugin's metric (no torch form) is computed on host copies of the batch."""
    from harness.metrics import batched

    ref, imgs, _, _ = _renders(12, 12, 5)
    monkeypatch.setattr(batched, "TORCH_METRICS", ("ssim",))  # psnr as if it had none
    side = batched.DeviceSide(ref, ("psnr", "ssim"), "cpu")
    assert side.other == ["psnr"] and side.single == ["ssim"]
    rows = batched.batch_values(side, torch.from_numpy(np.stack(imgs)), None)
    cpu = MetricSuite(names=("psnr",), device="cpu")
    cpu.reference("v", ref)
    assert [r["psnr"] for r in rows] == [r["psnr"] for r in cpu.score_many("v", imgs)]


def test_the_default_study_metrics_have_torch_forms():
    from harness.metrics import batched

    fams, single, other = batched._split(expand(["3dgs", "mpeg", "mpeg-qmiv"]))
    assert other == [] and set(single) == {"psnr", "ssim"} and set(fams) == {"mpeg", "mpeg-qmiv"}
