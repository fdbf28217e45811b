"""Synthetic rigs: seeded determinism, disjoint splits, the target in view, framing, auto choice."""

from __future__ import annotations

import numpy as np
import pytest

from harness.core.scene import GaussianScene
from harness.views.placement import placement
from harness.views.rigs import (
    SCENE_RIGS,
    choose_rig,
    held_out_indices,
    image_size,
    make_rig,
    scene_rig,
)
from tests.scene_factory import random_scene

RIGS = ("orbit", "room", "forward")


def blob(n=3000, seed=0) -> GaussianScene:
    return random_scene(n, seed=seed)


def room(seed=0) -> GaussianScene:
    """Walls of a 20 × 6 × 20 box (y down, floor at y = 3) around a dense object at the origin."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1, 1, size=(6000, 2))
    walls = [np.c_[np.full(1000, s * 10), u[:1000, 0] * 3, u[:1000, 1] * 10] for s in (-1, 1)]
    walls += [np.c_[u[:1000, 0] * 10, u[:1000, 1] * 3, np.full(1000, s * 10)] for s in (-1, 1)]
    floor = np.c_[u[:, 0] * 10, np.full(6000, 3.0), u[:, 1] * 10]
    obj = rng.normal(0, 0.5, size=(6000, 3))
    means = np.vstack([*walls, floor, obj])
    n = len(means)
    return GaussianScene.from_arrays(means, np.full((n, 3), -3.0), np.tile([1.0, 0, 0, 0], (n, 1)),
                                     np.full(n, 2.0), np.zeros((n, 3)))


def project(cam, p):
    x, y, z, _ = cam.world_to_cam @ np.r_[p, 1.0]
    return cam.fx * x / z + cam.cx, cam.fy * y / z + cam.cy, z


def projected(cam, pts):
    q = np.c_[pts, np.ones(len(pts))] @ cam.world_to_cam.T
    return cam.fx * q[:, 0] / q[:, 2] + cam.cx, cam.fy * q[:, 1] / q[:, 2] + cam.cy, q[:, 2]


@pytest.mark.parametrize("rig", RIGS)
def test_deterministic_in_seed(rig):
    s = blob()
    a, b, c = (make_rig(rig, s, n_train=10, n_test=3, seed=k) for k in (7, 7, 8))
    for x, y in zip(a.train + a.test, b.train + b.test):
        np.testing.assert_array_equal(x.world_to_cam, y.world_to_cam)
        assert (x.name, x.fx, x.width) == (y.name, y.fx, y.width)
    assert any(not np.allclose(x.world_to_cam, y.world_to_cam) for x, y in zip(a.test, c.test))


@pytest.mark.parametrize("rig", RIGS)
def test_train_test_disjoint(rig):
    views = make_rig(rig, blob(), n_train=20, n_test=5)
    assert (len(views.train), len(views.test)) == (20, 5)
    train, test = {c.name for c in views.train}, {c.name for c in views.test}
    assert len(train) == 20 and len(test) == 5 and not train & test
    centres = np.array([c.center for c in views.train + views.test])
    d = np.linalg.norm(centres[:, None] - centres[None], axis=-1) + np.eye(25)
    assert d.min() > 1e-6  # no test view duplicates a training view
    assert [int(c.name.split("_")[1]) for c in views.test] == held_out_indices(25, 5)


def test_held_out_indices_spread():
    assert held_out_indices(56, 8) == [3, 10, 17, 24, 31, 38, 45, 52]
    assert len(set(held_out_indices(9, 9))) == 9


@pytest.mark.parametrize("rig, scene_fn", [("orbit", blob), ("forward", blob), ("room", room), ("orbit", room)])
def test_every_test_view_sees_its_target(rig, scene_fn):
    scene = scene_fn()
    place = placement(scene)
    target = place.dense_center if rig == "room" else place.center
    views = make_rig(rig, scene, n_train=6, n_test=8, seed=1)
    for cam in views.test:
        u, v, z = project(cam, target)
        assert z > 0.2
        assert 0 <= u < cam.width and 0 <= v < cam.height
        assert (u, v) == pytest.approx((cam.width / 2, cam.height / 2), abs=1e-6)  # looked at


@pytest.mark.parametrize("rig", ["orbit", "forward"])
def test_content_fills_the_frame(rig):
    scene = blob()
    place = placement(scene)
    for cam in make_rig(rig, scene, n_train=4, n_test=6).test:
        u, v, z = projected(cam, place.points)
        inside = (z > 0.2) & (u >= 0) & (u < cam.width) & (v >= 0) & (v < cam.height)
        assert inside.mean() >= 0.98
        span_u = (np.percentile(u, 99) - np.percentile(u, 1)) / cam.width
        span_v = (np.percentile(v, 99) - np.percentile(v, 1)) / cam.height
        assert max(span_u, span_v) >= 0.6  # not a distant speck


def test_room_cameras_stay_inside_and_look_down():
    scene = room()
    views = make_rig("room", scene, n_train=4, n_test=8, up=(0, -1, 0), elevations=(30.0,))
    for cam in views.test:
        assert np.all(np.abs(cam.center) < [10, 3, 10])  # inside the walls
        assert cam.center[1] < 0 and cam.forward[1] > 0  # above the object, looking down (y down)


def test_up_is_drawn_upwards():
    scene = blob()
    place = placement(scene, up=(0, 0, 1))
    for cam in make_rig("orbit", scene, n_train=2, n_test=4, up=(0, 0, 1)).test:
        _, v, _ = project(cam, place.center + 0.3 * place.radius * np.array([0, 0, 1.0]))
        assert v < cam.height / 2


def test_image_size_and_aspect():
    assert image_size(1024, 4 / 3) == (1024, 768)
    assert image_size(1024, 0.5) == (512, 1024)
    cam = make_rig("orbit", blob(), n_train=1, n_test=1, longest_side=300, aspect=2.0).test[0]
    assert (cam.width, cam.height) == (300, 150)
    assert cam.fov_x == pytest.approx(np.radians(60.0))


def test_auto_choice():
    assert choose_rig(placement(blob())) == "orbit"
    assert choose_rig(placement(room(), up=(0, -1, 0))) == "room"
    assert make_rig("auto", room(), n_train=2, n_test=2, up=(0, -1, 0)).rig == "room"


def test_dataset_table_and_explicit_rigs():
    from harness.io.datasets import SCENES

    assert set(SCENE_RIGS) <= set(SCENES)  # keyed by dataset name, never by file name
    assert set(SCENE_RIGS) == {"grape-small", "luigi", "bonsai-7k-mini", "bonsai-7k", "playbot", "synth-room",
                               "synth-statue"}
    scene = blob()
    views = scene_rig("playbot", scene, n_train=2, n_test=4)
    up = np.array(SCENE_RIGS["playbot"].up)
    place = placement(scene, up=up)
    assert views.rig == SCENE_RIGS["playbot"].rig
    for cam in views.test:  # table elevations (all ≥ 20° − jitter) put cameras above the centre
        assert (cam.center - place.center) @ up > 0
    assert scene_rig(None, scene, n_train=2, n_test=2).rig == "orbit"  # default of an unknown scene: auto
    # an explicit rig uses its flags alone: the dataset's table (up, aspect) does not leak in
    a = scene_rig("luigi", scene, "orbit", n_train=2, n_test=2)
    b = scene_rig(None, scene, "orbit", n_train=2, n_test=2)
    assert [c.to_dict() for c in a.test] == [c.to_dict() for c in b.test]
    # the table's aspect applies to `default` unless one is given explicitly (the runner's aspect bug)
    assert scene_rig("luigi", scene, n_train=1, n_test=1, longest_side=512).test[0].height == 512
    wide = scene_rig("luigi", scene, n_train=1, n_test=1, longest_side=512, aspect=2.0).test[0]
    assert (wide.width, wide.height) == (512, 256)


def test_bad_arguments():
    with pytest.raises(ValueError, match="unknown rig"):
        make_rig("spiral", blob())
    with pytest.raises(ValueError, match="n_test"):
        make_rig("orbit", blob(), n_test=0)
    with pytest.raises(ValueError, match="empty scene"):
        make_rig("orbit", blob().subset(np.zeros(3000, bool)))


@pytest.mark.parametrize("dataset, aspect, size", [
    ("bonsai-7k", None, (512, 384)), ("bonsai-7k", 1.0, (512, 512)), ("bonsai-7k", 2.0, (512, 256)),
    ("luigi", None, (512, 512)), ("luigi", 2.0, (512, 256)), (None, None, (512, 384))])
def test_run_rig_honours_the_protocol_aspect(dataset, aspect, size):
    """The runner's rig for a named scene used to drop the config's aspect (yet keyed the cache on it)."""
    from harness.run.toolkit import make_rig as run_rig

    _, _, test = run_rig("default", blob(), kind="object-centric", dataset=dataset, n_train=1, n_test=1,
                         longest_side=512, aspect=aspect, seed=0)
    assert (test[0].width, test[0].height) == size


def test_shifted_protocol_views_come_from_another_distribution():
    """The shifted protocol's test views sit on higher rings, with a narrower field of view, at other
    azimuths than the rig's — no test camera coincides with a training camera's distribution."""
    from harness.views.protocols import ViewRequest, protocol

    scene = blob()
    place = placement(scene)
    rig = scene_rig(None, scene, "orbit", n_train=12, n_test=6)
    shifted = protocol("shifted").views(ViewRequest("b", None, "orbit", "object-centric", 12, 6, 1024, None, 0,
                                                    lambda: scene, lambda: list(rig.test))).test

    def elevation(cam):
        d = cam.center - place.center
        return np.degrees(np.arcsin(d @ place.up / np.linalg.norm(d)))

    assert min(elevation(c) for c in shifted) > max(elevation(c) for c in rig.train) - 5.0
    assert np.mean([elevation(c) for c in shifted]) > np.mean([elevation(c) for c in rig.train]) + 15.0
    assert all(c.fov_x < 0.7 * rig.train[0].fov_x for c in shifted)
