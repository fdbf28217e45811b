"""What a view sees, for the cost model: splats in front of the camera, drawn, and their footprints
per pixel — against scenes whose answer is known by hand — and the estimate costing each view by it."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from harness.core.cameras import Camera
from harness.core.scene import GaussianScene
from harness.run.estimate import IMAGE_OVERHEAD_S, estimate
from harness.run.view_coverage import Coverage, coverage, footprint, is_rig_shaped, look, sample
from tests.test_plan import _tiny, _units


def _splats(means, sigma=0.5) -> GaussianScene:
    n = len(means)
    return GaussianScene.from_arrays(means=np.asarray(means, np.float64), scales_log=np.full((n, 3), math.log(sigma)),
                                     quats=np.tile([1.0, 0, 0, 0], (n, 1)), opacity_logit=np.full(n, 5.0),
                                     sh_dc=np.zeros((n, 3)), sh_rest=np.zeros((n, 0, 3)))


CAM = Camera.look_at((0, 0, -5), (0, 0, 0), fov_y_deg=60.0, width=64, height=64)


def test_a_splat_behind_the_camera_and_one_beside_the_view_are_not_drawn():
    # at the origin (5 in front: drawn), behind the camera, and far to the side (in front, not in the image)
    got = coverage(_splats([(0, 0, 0), (0, 0, -10), (100, 0, 0)]), CAM)
    assert got.front == pytest.approx(2 / 3) and got.visible == pytest.approx(1 / 3)
    # the drawn splat's ±3σ box: σ = fy·0.5/5 px with fy = 32 / tan 30°; + the 0.3 px² dilation: r = 17
    sigma_px = 32 / math.tan(math.radians(30)) * 0.5 / 5
    r = math.ceil(3 * math.sqrt(sigma_px ** 2 + 0.3))
    assert r == 17 and got.overdraw == pytest.approx((2 * r) ** 2 / 64 ** 2)


def test_a_sample_stands_for_the_whole_scene_and_footprints_are_clipped_to_the_image():
    one = _splats([(0, 0, 0)] * 4)
    whole = coverage(one, CAM)
    assert coverage(one.subset(np.arange(2)), CAM, total=4) == whole  # 2 of 4 identical splats: the same view
    assert footprint(np.array([[0.0, 0.0], [63.0, 10.0]]), np.array([10.0, 2.0]), 64, 64) == 10 * 10 + 3 * 4
    assert sample(one) is one and len(sample(_splats(np.zeros((25_000, 3))))) == 20_000


def test_the_draw_of_a_view_counts_its_visible_splats_its_fragments_and_its_pixels():
    u = _units(draw_splat=2.0, fragment_px=3.0, image_px=5.0, front_splat=7.0, visible_splat=11.0,
               seen=Coverage(1.0, 1.0, 4.0))
    half = Coverage(front=0.8, visible=0.5, overdraw=10.0)
    # keep 0.25 of 100 splats at 20 pixels: 0.25·(2·100·0.5 + 3·10·20) + 5·20
    assert u.draw_view(100, 20, half, keep=0.25) == pytest.approx(0.25 * (100 + 600) + 100)
    assert u.pack_view(100, half) == pytest.approx(100 * (7 * 0.8 + 11 * 0.5))
    assert u.render_view(100, 20, None) == pytest.approx(100 * 18 + 2 * 100 + 3 * 4 * 20 + 5 * 20)  # calibration's view
    plain = _units(render_splat=2.0, render_px=3.0, pack_splat=0.5)  # not calibrated: the splat + pixel model
    assert not plain.covered and plain.draw_view(100, 20, half, 0.25) == pytest.approx(1.5 * 25 + 3 * 20)


def test_the_estimate_costs_each_view_by_what_it_sees(tmp_path):
    config, infos = _tiny(tmp_path)
    look(infos, config, tmp_path)
    assert all(i.seen is not None for i in infos)
    u = _units(draw_splat=1.0, seen=Coverage(1.0, 1.0, 0.0))  # a second per drawn splat, nothing else
    est = estimate(config, infos, u)
    want = 48 * IMAGE_OVERHEAD_S  # 48 images
    for info in infos:
        for proto in ("rig", "shifted"):
            covs = info.seen.of_views(proto)
            assert len(covs) == 3 and all(0 <= c.visible <= c.front <= 1 for c in covs)
            # the reference render, and 2 methods × 2 ratios (keep 0.9, 0.7) drawn from the packing
            want += sum(info.splats[0] * c.visible * (1 + 2 * (0.9 + 0.7)) for c in covs)
    assert est.stages["render_ref"].core_s + est.stages["render+metrics"].core_s == pytest.approx(want)
    blind = estimate(config, [replace(i, seen=None) for i in infos], u)  # unseen: the calibration's full view
    assert blind.stages["render_ref"].core_s == pytest.approx(sum(6 * i.splats[0] for i in infos))


def test_a_virtual_rig_is_told_by_its_parameters():
    from methods.registry import get_pruner

    assert is_rig_shaped(get_pruner("virtual-rig").params()) and is_rig_shaped(get_pruner("betadesc-vr").params())
    assert not is_rig_shaped(get_pruner("lightgs").params()) and not is_rig_shaped({"views": 3})


def test_calibration_unit_costs_are_never_negative():
    from harness.run.calibrate import _solve

    assert _solve([[1, 0], [0, 1]], [2, 3]) == pytest.approx((2, 3))
    x, y = _solve([[1, 1], [1, 2]], [2, 1])  # exact solution (3, -1): y is 0, x refitted
    assert y == 0.0 and x == pytest.approx(1.5)


def test_a_sequence_is_looked_at_from_its_first_frame_only(tmp_path):
    from harness.io.ply import write_ply
    from harness.run.config import parse_config
    from harness.run.scene_sizes import Assumptions, scene_info
    from harness.run.toolkit import Toolkit
    from tests.scene_factory import random_scene

    for i in range(3):
        write_ply(random_scene(50 + i, seed=i), tmp_path / f"f{i}.ply")
    config = parse_config({"protocol": {"longest_side": 64, "n_test": 2, "n_train": 2}, "methods": ["opacity"],
                           "ratios": [0.5], "scenes": [{"name": "seq", "frames": str(tmp_path / "f*.ply")}]},
                          str(tmp_path / "c.yaml"))
    infos = [scene_info(s, config, Assumptions()) for s in config.scenes]
    read, plain = [], Toolkit()
    toolkit = replace(plain, load_scene=lambda path, lod=None: read.append(path) or plain.load_scene(path, lod))
    look(infos, config, tmp_path, toolkit)
    assert infos[0].splats == [50, 51, 52] and len(infos[0].seen.of_views("rig")) == 2
    assert {str(p) for p in read} == {str(tmp_path / "f0.ply")}  # the other frames are not read
