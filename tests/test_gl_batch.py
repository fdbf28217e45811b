"""The GL renderer's batch: several pruned sets of a view drawn before the first read-back, each
bit for bit its own draw (so a study on a GPU waits for the device once per batch, not per image);
and the batch handed to the metrics as one tensor on the study's device (renderers.readback), each
image and alpha bit for bit its draw, the scores those of the host arrays. That runs on CPU torch
here (the same code as on CUDA, without the pinned buffer); the CUDA cases skip without a GPU."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from harness.core.cameras import Camera
from harness.run.view_renders import ViewRenders, host_array, stacked
from renderers import BATCH, DEVICE_BATCH, capabilities
from renderers.arrays import NUMPY, torch_ops
from renderers.gl import GLRenderer
from tests.gl_support import require_gl
from tests.scene_factory import random_scene

pytestmark = pytest.mark.gl
BG = (0.2, 0.3, 0.4)


@pytest.fixture(scope="module")
def gl():
    require_gl()
    renderer = GLRenderer()
    yield renderer
    renderer.close()


def _view(width=48, height=36):
    return Camera.look_at((0.3, 0.4, 4.0), (0.0, 0.0, 0.0), fov_y_deg=50, width=width, height=height)


def _keeps(n, count, seed=0):
    rng = np.random.default_rng(seed)
    return [rng.random(n) < f for f in np.linspace(0.2, 0.9, count)] + [np.zeros(n, bool), np.ones(n, bool)]


def _pruned_views(gl, count):
    """``count`` random pruned sets of one view, then the empty and the whole set, packed."""
    scene = random_scene(400, sh_degree=1, seed=3)
    packed = gl.pack(scene, _view())
    return [packed.kept(k) for k in _keeps(len(scene), count)]


@pytest.mark.parametrize("with_alpha", [False, True])
def test_draw_many_is_each_draw_bit_for_bit(gl, with_alpha):
    assert BATCH in capabilities(gl)
    views = _pruned_views(gl, 4)
    batch = gl.draw_many(views, (0.2, 0.3, 0.4), with_alpha=with_alpha)
    one_by_one = [gl.draw(v, (0.2, 0.3, 0.4), with_alpha=with_alpha) for v in views]
    assert len(batch) == len(views)
    for got, want in zip(batch, one_by_one):
        for g, w in zip(got, want) if with_alpha else [(got, want)]:
            assert g.dtype == w.dtype and np.array_equal(g, w)
    # the empty set is the background; the whole set is not
    whole = batch[-1][0] if with_alpha else batch[-1]
    assert not np.array_equal(whole, np.broadcast_to(np.float32([0.2, 0.3, 0.4]), (36, 48, 3)))
    assert np.array_equal(batch[-2][0] if with_alpha else batch[-2],
                          np.broadcast_to(np.float32([0.2, 0.3, 0.4]), (36, 48, 3)))


def test_views_of_other_sizes_or_tiled_are_drawn_one_by_one(gl):
    scene = random_scene(200, sh_degree=0, seed=4)
    views = [gl.pack(scene, _view()), gl.pack(scene, _view(40, 30))]
    got = gl.draw_many(views)
    assert [g.shape for g in got] == [(36, 48, 3), (30, 40, 3)]
    assert all(np.array_equal(g, gl.draw(v)) for g, v in zip(got, views))
    small = GLRenderer(max_tile=16)  # every image tiled
    try:
        packed = small.pack(scene, _view())
        views = [packed.kept(k) for k in _keeps(len(scene), 2, seed=1)]
        assert all(np.array_equal(g, small.draw(v)) for g, v in zip(small.draw_many(views), views))
    finally:
        small.close()


def test_a_views_renders_in_a_batch_equal_its_renders_one_by_one(gl):
    scene = random_scene(300, sh_degree=1, seed=5)
    renders = ViewRenders(gl, scene, _view(), (0.0, 0.0, 0.0), with_alpha=True)
    keeps = _keeps(len(scene), 3, seed=2)
    for (img, alpha), (img1, alpha1) in zip(renders.many(keeps), [renders(k) for k in keeps]):
        assert np.array_equal(img, img1) and np.array_equal(alpha, alpha1)


@pytest.mark.parametrize("with_alpha", [False, True])
def test_a_batch_on_the_device_is_each_draw_bit_for_bit(gl, with_alpha):
    assert DEVICE_BATCH in capabilities(gl)
    views = _pruned_views(gl, 3)
    images, alphas = gl.draw_many_on(views, "cpu", BG, with_alpha=with_alpha)
    assert images.shape == (len(views), 36, 48, 3) and images.dtype == torch.float32
    assert (alphas is not None) == with_alpha
    for i, v in enumerate(views):
        want = gl.draw(v, BG, with_alpha=True)
        assert np.array_equal(images[i].numpy(), want[0])
        if with_alpha:
            assert np.array_equal(alphas[i].numpy(), want[1])
    one = gl.draw_many_on(views[:1], "cpu", BG)[0]  # a batch of one goes the same way
    assert np.array_equal(one[0].numpy(), gl.draw(views[0], BG))


def test_tiled_views_are_drawn_one_by_one_and_sizes_must_agree(gl):
    scene = random_scene(200, sh_degree=0, seed=4)
    small = GLRenderer(max_tile=16)  # every image tiled
    try:
        packed = small.pack(scene, _view())
        views = [packed.kept(k) for k in _keeps(len(scene), 3, seed=1)]
        images, alphas = small.draw_many_on(views, "cpu", BG, with_alpha=True)
        for i, v in enumerate(views):
            img, alpha = small.draw(v, BG, with_alpha=True)
            assert np.array_equal(images[i].numpy(), img) and np.array_equal(alphas[i].numpy(), alpha)
    finally:
        small.close()
    with pytest.raises(ValueError, match="one size"):
        gl.draw_many_on([gl.pack(scene, _view()), gl.pack(scene, _view(40, 30))], "cpu")


def test_frames_stay_on_the_host_off_cuda(gl):
    scene = random_scene(50, seed=1)
    assert not ViewRenders(gl, scene, _view(), BG, True).frames_on_device()
    assert not ViewRenders(gl, scene, _view(), BG, True, "cpu").frames_on_device()
    assert ViewRenders(gl, scene, _view(), BG, True, "cuda").frames_on_device() == torch.cuda.is_available()
    arrays = [np.zeros((2, 2, 3), np.float32)]
    assert stacked(arrays) is arrays and stacked([None]) == [None] and host_array(arrays[0]) is arrays[0]


def test_records_reach_the_host_in_one_wait():
    x, ids = torch.arange(12.0).reshape(4, 3), torch.arange(4)
    for got, want in zip(torch_ops().to_host(x, ids), (x.numpy(), ids.numpy())):
        assert np.array_equal(got, want) and got.dtype == want.dtype
    assert np.array_equal(NUMPY.to_host(np.ones(3))[0], np.ones(3))


def test_a_views_sets_scored_from_device_frames_equal_the_host_frames(gl, monkeypatch):
    """The study's wiring (harness.run.tasks._measure_sets): with the frames on the device, every
    stored metric is the host path's, the PNG too."""
    from harness.metrics.suite import MetricSuite
    from harness.run import tasks

    scene = random_scene(300, sh_degree=1, seed=5)
    keeps = _keeps(len(scene), 3, seed=2)[:3]
    names = ("psnr", "ssim", "rgb_psnr", "rgb_psnr_om", "yuv_ssim_om")

    class Cache:
        def __init__(self):
            self.json, self.png = {}, {}

        def get_array(self, stage, key, count=False, check=None):
            return np.packbits(keeps[int(key)])

        def put_json(self, stage, key, rec):
            self.json[key] = rec

        def put_bytes(self, stage, key, suffix, data):
            self.png[key] = data

    batches = []
    draw_many_on = GLRenderer.draw_many_on
    monkeypatch.setattr(GLRenderer, "draw_many_on",
                        lambda self, *a, **k: batches.append(1) or draw_many_on(self, *a, **k))

    def measure(on_device):
        monkeypatch.setattr(ViewRenders, "frames_on_device", lambda self: on_device)
        renders = ViewRenders(gl, scene, _view(), BG, True, "cpu")
        ref, ref_alpha = renders()
        suite = MetricSuite(names=names, device="cpu", torch_forms=True, batch=3)
        suite.reference("r", ref, alpha=ref_alpha)
        task = tasks.ViewTask("c", "r", "p", None, "d", len(scene), {}, "gl", "cpu", BG, names, [])
        jobs = [tasks.MaskJob(f"m{i}", str(i), png=i == 0) for i in range(len(keeps))]
        cache = Cache()
        out = tasks._measure_sets(task, cache, suite, renders, jobs, 0.0, True)
        assert all(err is None for _, err in out)
        return cache

    host = measure(False)
    assert not batches
    device = measure(True)
    assert batches == [1]
    seconds = ("render_s", "metrics_s", "ref_features_s", "view_pack_s")
    for key, rec in host.json.items():
        assert {k: v for k, v in device.json[key].items() if k not in seconds} == \
            {k: v for k, v in rec.items() if k not in seconds}
    assert host.png and device.png == host.png


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device: the pinned read-back is checked on "
                    "CPU torch above, without pinning")
def test_cuda_batch_through_pinned_memory_is_each_draw(gl):
    views = _pruned_views(gl, 3)
    images, alphas = gl.draw_many_on(views, "cuda", BG, with_alpha=True)
    assert images.device.type == "cuda"
    for i, v in enumerate(views):
        img, alpha = gl.draw(v, BG, with_alpha=True)
        assert np.array_equal(images[i].cpu().numpy(), img) and np.array_equal(alphas[i].cpu().numpy(), alpha)
    x = torch.arange(12.0, device="cuda")
    assert np.array_equal(torch_ops().to_host(x)[0], np.arange(12.0, dtype=np.float32))
