"""The GL renderer's batch: several pruned sets of a view drawn before the first read-back, each
bit for bit its own draw (so a study on a GPU waits for the device once per batch, not per image)."""

from __future__ import annotations

import numpy as np
import pytest

from harness.core.cameras import Camera
from harness.run.view_renders import ViewRenders
from renderers import BATCH, capabilities
from renderers.gl import GLRenderer
from tests.gl_support import require_gl
from tests.scene_factory import random_scene

pytestmark = pytest.mark.gl


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


@pytest.mark.parametrize("with_alpha", [False, True])
def test_draw_many_is_each_draw_bit_for_bit(gl, with_alpha):
    assert BATCH in capabilities(gl)
    scene = random_scene(400, sh_degree=1, seed=3)
    packed = gl.pack(scene, _view())
    views = [packed.kept(k) for k in _keeps(len(scene), 4)]
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
