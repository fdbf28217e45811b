"""Views composited together (renderers.reference.composite_views, the LightGS significance's torch
backend) against the same views one at a time and against the CPU's sweep: equal to float rounding."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from harness.core.cameras import Camera
from methods import PruneContext, get_pruner
from methods.lightgs.significance import significance
from methods.virtualrig import VirtualRigParams, virtual_cameras
from renderers import reference
from renderers.projection import SplatTensors, project_gaussians
from tests.test_sweep import _scene


def _views():
    """Five views, two sizes (interleaved, so grouping by size reorders them)."""
    up = np.array([0.0, -1.0, 0.0])
    spec = [((0.2, -0.3, -4.0), 64, 48), ((3.0, -1.0, 1.5), 40, 52), ((-2.5, -1.5, 2.0), 64, 48),
            ((0.5, 2.5, 3.0), 40, 52), ((-3.5, 0.5, -1.0), 64, 48)]
    return [Camera.look_at(np.array(e), np.zeros(3), up, fov_y_deg=60.0, width=w, height=h, name=f"v{i}")
            for i, (e, w, h) in enumerate(spec)]


def _projections(scene, views):
    st = SplatTensors.from_scene(scene, device="cpu")
    with torch.no_grad():
        return st, [project_gaussians(st, v) for v in views]


@pytest.mark.parametrize("early_stop", [True, False])
@pytest.mark.parametrize("budget", [reference.DEFAULT_BUDGET, 1 << 13])
def test_views_together_equal_each_alone(early_stop, budget):
    """Images, alpha and every per-splat statistic of a stacked batch are each view's own render;
    the small budget splits the batch's tiles into groups and caps the blocks' depth."""
    scene = _scene()
    st, projs = _projections(scene, [v for v in _views() if v.width == 64])
    with torch.no_grad():
        alone = [reference.composite(p, len(st), (0.1, 0.2, 0.3), stats=True, early_stop=early_stop) for p in projs]
        together = reference.composite_views(projs, len(st), (0.1, 0.2, 0.3), stats=True, early_stop=early_stop,
                                             budget=budget)
    assert len(together) == len(alone) == 3
    for a, b in zip(alone, together):
        assert b.image.shape == a.image.shape == (48, 64, 3)
        np.testing.assert_allclose(b.image.numpy(), a.image.numpy(), rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(b.alpha.numpy(), a.alpha.numpy(), rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(b.opacity_t.numpy(), a.opacity_t.numpy(), rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(b.alpha_t.numpy(), a.alpha_t.numpy(), rtol=1e-5, atol=1e-5)
        assert np.abs(b.hits.numpy() - a.hits.numpy()).max() <= 1  # a pixel at the 1e-4 stop may flip
        assert (a.hits > 0).sum() > 100


def test_one_view_is_composite_bit_for_bit():
    scene = _scene()
    st, projs = _projections(scene, _views()[:1])
    with torch.no_grad():
        a = reference.composite(projs[0], len(st), stats=True, early_stop=True, budget=1 << 14)
        (b,) = reference.composite_views(projs, len(st), stats=True, early_stop=True, budget=1 << 14)
    for x, y in ((a.image, b.image), (a.opacity_t, b.opacity_t), (a.hits, b.hits)):
        assert torch.equal(x, y)


def test_views_of_different_sizes_cannot_be_stacked():
    scene = _scene(200)
    st, projs = _projections(scene, _views()[:2])
    with pytest.raises(ValueError, match="views of one size"):
        reference.composite_views(projs, len(st))


@pytest.mark.parametrize("early_stop", [True, False])
def test_significance_batched_equals_view_by_view_and_the_sweep(early_stop):
    """Views of two sizes in one call, batched 1, 2 and by memory: the same sums as one by one, and
    as the CPU's sweep backend (the reference retires tiles below T = 1e-7: effects below that)."""
    scene, views = _scene(), _views()
    one = significance(scene, views, longest_side=0, early_stop=early_stop, backend="reference", views_per_call=1)
    swept = significance(scene, views, longest_side=0, early_stop=early_stop, backend="sweep")
    assert (swept > 0).sum() > 500
    np.testing.assert_allclose(one, swept, rtol=1e-4, atol=1e-5)
    for per_call in (2, None):
        got = significance(scene, views, longest_side=0, early_stop=early_stop, backend="reference",
                           views_per_call=per_call)
        np.testing.assert_allclose(got, one, rtol=1e-5, atol=1e-6)


def test_batch_size_follows_the_budget():
    assert reference.device_budget("cpu") == reference.DEFAULT_BUDGET
    # 64 × 48 px = 8 × 6 tiles of 8 px: a group of ≥ 8-deep blocks holds budget / (8·64) tiles
    assert reference.views_per_call(64, 48, budget=8 * 64 * 48 * 3) == 3
    assert reference.views_per_call(64, 48, budget=8 * 64 * 48 * 3 - 1) == 2
    assert reference.views_per_call(4096, 4096, budget=1) == 1
    assert reference.views_per_call(8, 8) == reference.MAX_VIEWS


def test_virtual_rig_batched_on_torch_equals_its_cpu_score():
    """The virtual rig's views through the batched torch backend (its CUDA path, here on CPU torch)."""
    from tests.test_virtualrig import _small_object

    scene = _small_object()
    params = {"views": 6, "resolution": 40}
    cpu = get_pruner("virtual-rig").score(scene, PruneContext(params=params))
    _, cams = virtual_cameras(scene, VirtualRigParams.parse(params))
    batched = significance(scene, cams, longest_side=0, early_stop=True, backend="reference")
    alone = significance(scene, cams, longest_side=0, early_stop=True, backend="reference", views_per_call=1)
    np.testing.assert_allclose(batched, alone, rtol=1e-5, atol=1e-6)
    from methods.lightgs.significance import volume_factor

    np.testing.assert_allclose(batched * volume_factor(scene.scales_log), cpu, rtol=1e-4, atol=1e-5)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device: the batched backend is checked on "
                    "CPU torch above")
@pytest.mark.parametrize("early_stop", [True, False])
def test_cuda_batched_equals_the_sweep(early_stop):
    scene, views = _scene(), _views()
    got = significance(scene, views, longest_side=0, early_stop=early_stop, device="cuda")
    swept = significance(scene, views, longest_side=0, early_stop=early_stop, backend="sweep")
    np.testing.assert_allclose(got, swept, rtol=1e-4, atol=1e-5)
    assert reference.device_budget("cuda") >= reference.DEFAULT_BUDGET
