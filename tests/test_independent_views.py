"""The ``independent`` held-out protocol: random views seeded per scene, from a distribution that
shares nothing with the training rig but where a camera can be (:mod:`harness.views.independent`)."""

from __future__ import annotations

import math

import numpy as np
import torch

from harness.core.cameras import Camera
from harness.run.config import load_config, parse_config
from harness.run.toolkit import Toolkit
from harness.views.independent import CLOSE_UP_SHARE, FOV_RANGE, independent_views, scene_seed
from harness.views.placement import placement
from harness.views.protocols import ViewRequest, protocol
from harness.views.rigs import scene_rig
from renderers.projection import project_gaussians
from tests.test_rigs import blob, room
from tests.test_virtualrig import REPO


def _same(a: list[Camera], b: list[Camera]) -> bool:
    return all(np.array_equal(x.world_to_cam, y.world_to_cam) and x.fx == y.fx for x, y in zip(a, b))


def test_seeded_per_scene():
    a, b = blob(seed=0), blob(seed=1)
    va = independent_views(None, a, "orbit", n_test=8, longest_side=96, seed=5)
    assert _same(va, independent_views(None, a, "orbit", n_test=8, longest_side=96, seed=5))
    assert not _same(va, independent_views(None, b, "orbit", n_test=8, longest_side=96, seed=5))
    assert not _same(va, independent_views(None, a, "orbit", n_test=8, longest_side=96, seed=6))
    assert scene_seed(a, 5) != scene_seed(b, 5) and scene_seed(a, 5)[0] == 5


def test_random_fields_of_view_and_every_view_sees_content():
    scene = blob()
    cams = independent_views(None, scene, "orbit", n_test=40, longest_side=96, aspect=4 / 3, seed=0)
    assert [c.name for c in cams] == [f"independent_{i:03d}" for i in range(40)]
    assert all((c.width, c.height) == (96, 72) for c in cams)
    fov = np.degrees([c.fov_x for c in cams])
    assert FOV_RANGE[0] <= fov.min() and fov.max() <= FOV_RANGE[1] and np.ptp(fov) > 25.0
    rig = scene_rig(None, scene, "orbit", n_train=16, n_test=8, longest_side=96)
    assert not any(math.isclose(f, math.degrees(rig.train[0].fov_x), abs_tol=1e-6) for f in fov)
    with torch.no_grad():
        seen = [len(project_gaussians(scene, c, device="cpu").ids) for c in cams]
    assert min(seen) > 0.05 * len(scene)
    # close-ups: about a quarter of the views stand nearer the content than the regular ones
    place = placement(scene)
    d = np.array([np.linalg.norm(c.center - place.center) for c in cams])
    assert 0.1 < np.mean(d < 0.8 * np.median(d)) < 0.5 and CLOSE_UP_SHARE == 0.25


def test_room_views_stand_inside_the_room():
    scene = room()
    cams = independent_views(None, scene, "room", n_test=24, longest_side=64, seed=0)
    eyes = np.array([c.center for c in cams])
    assert np.all(np.abs(eyes[:, [0, 2]]) < 10.0) and np.all(eyes[:, 1] < 3.0)  # inside walls, above the floor


def request(scene, **over) -> ViewRequest:
    """What a run asks a protocol for an orbit scene of its own file."""
    base = dict(name="b", dataset=None, rig="orbit", kind="object-centric", n_train=0, n_test=3, longest_side=64,
                aspect=None, seed=0, scene=lambda: scene, held_out=lambda: [])
    return ViewRequest(**{**base, **over})


def test_protocol_plugs_into_the_runner_like_shifted():
    proto = protocol("independent")
    assert not proto.primary and proto.params.seed_offset == 2000
    cams = proto.views(request(blob())).test
    direct = independent_views(None, blob(), "orbit", n_test=3, longest_side=64, seed=proto.params.seed_offset)
    assert [c.name for c in cams] == [f"independent_{i:03d}" for i in range(3)]  # the run names them independent/...
    assert _same(cams, direct)
    assert proto.views(request(blob(), synthetic=False)) is None  # a camera file's scene has no such views
    assert "harness.views.independent" in Toolkit().rig_modules  # its code versions the cached views
    cfg = parse_config({"scenes": [{"name": "luigi"}], "methods": ["opacity"], "ratios": [0.1],
                        "protocols": ["rig", "shifted", "independent"]}, "c.yaml")
    assert [p.name for p in cfg.protocols] == ["rig", "shifted", "independent"]


def test_virtualrig_configs_are_valid():
    for name in ("virtualrig", "virtualrig_confirm"):
        cfg = load_config(REPO / "ctc_configs" / "study" / f"{name}.yaml")
        assert [p.name for p in cfg.protocols] == ["rig", "shifted", "independent"]
        assert {"virtual-rig", "betadesc-vr", "lightgs"} <= {m.method for m in cfg.methods}
