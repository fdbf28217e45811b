"""The `real` protocol end to end, in-process with the runner fakes: a scene carrying a capture,
camera-aware scores per training set, photo metrics checked against an independent recomputation,
the cache keyed on the photo's content, the photos table and figure."""

from __future__ import annotations

import math

import numpy as np
import pytest
from PIL import Image

from harness.core.cameras import Camera
from harness.io.cameras import write_3dgs_cameras
from harness.io.photos import read_photo
from harness.io.scenes import load_scene, write_scene
from harness.metrics.psnr import psnr
from harness.report.results import to_frame
from harness.run.config import parse_config
from harness.run.runner import Runner
from methods.targeting import select_by_ratio
from tests import runner_fakes as fakes
from tests.scene_factory import random_scene


@pytest.fixture
def world(tmp_path):
    """A 300-splat scene and its 'capture': 6 cameras at 64x48, photos = the scene's own render
    (point renderer) plus a little noise, held out: img0, img2, img4."""
    scene = random_scene(300, sh_degree=1, seed=0)
    write_scene(scene, tmp_path / "s.ply")
    scene = load_scene(tmp_path / "s.ply")
    cams = [Camera.look_at((5 * math.cos(2 * math.pi * i / 6), 0.5, 5 * math.sin(2 * math.pi * i / 6)), (0, 0, 0),
                           fov_y_deg=40, width=64, height=48, name=f"img{i}") for i in range(6)]
    write_3dgs_cameras(cams, tmp_path / "cap" / "cameras.json")
    (tmp_path / "cap" / "photos").mkdir()
    rng = np.random.default_rng(1)
    for c in cams:
        img = fakes.PointRenderer().render(scene, c) + rng.normal(0, 0.03, (48, 64, 3))
        Image.fromarray((np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)).save(
            tmp_path / "cap" / "photos" / f"{c.name}.png"
        )
    capture = {"cameras": str(tmp_path / "cap" / "cameras.json"), "images": str(tmp_path / "cap" / "photos"),
               "test": ["img0", "img2", "img4"]}
    return tmp_path, scene, cams, capture


def config(tmp_path, capture, protocols, methods=("fake-norm", "fake-aware"), extra_scene=None):
    scenes = [{"name": "s", "source": str(tmp_path / "s.ply"), "capture": capture}] + (
        [extra_scene] if extra_scene else []
    )
    return parse_config({"name": "t", "protocol": {"longest_side": 32, "metrics": ["psnr", "ssim"], "n_train": 3,
                                                   "n_test": 2},
                         "protocols": protocols, "ratios": [0.1, 0.3], "scenes": scenes, "methods": list(methods),
                         "tables": ["comparison", "photos"], "plots": ["photos"]}, str(tmp_path / "t.yaml"))


def run(cfg, tmp_path):
    r = Runner(cfg, out_dir=tmp_path / "out", cache_root=tmp_path / "cache", toolkit=fakes.toolkit(),
               log=lambda m: None, base_dir=tmp_path)
    res = r.run()
    return res, to_frame(res.rows)


def test_real_views_carry_photo_metrics_that_match_an_independent_recomputation(world):
    tmp_path, scene, cams, capture = world
    fakes.CALLS.clear()
    res, df = run(config(tmp_path, capture, ["rig", "real"]), tmp_path)
    assert not res.errors and (df["status"] == "ok").all()
    real, rig = df[df["protocol"] == "real"], df[df["protocol"] == "rig"]
    assert sorted(set(real["view"])) == ["real/img0", "real/img2", "real/img4"] and len(rig) == 2 * 2 * 2
    assert rig["gt_psnr"].isna().all() and real["gt_psnr"].notna().all()
    assert (real["width"] == 32).all() and (real["height"] == 24).all()
    # camera-aware: scored on the rig's and on the capture's training cameras; camera-free: once
    assert fakes.CALLS["score:fake-aware"] == 2 and fakes.CALLS["score:fake-norm"] == 1

    renderer = fakes.PointRenderer()
    for view, cam in ((f"real/{c.name}", c.resized(32)) for c in cams if c.name in ("img0", "img2", "img4")):
        photo = read_photo(tmp_path / "cap" / "photos" / f"{view[5:]}.png", 32, 24)
        rows = real[(real["view"] == view) & (real["method"] == "fake-norm")]
        assert np.allclose(rows["unpruned_gt_psnr"], psnr(photo, renderer.render(scene, cam)))
        for _, row in rows.iterrows():
            keep = select_by_ratio(-np.linalg.norm(scene.means.astype(np.float64), axis=1), row["ratio"]).keep
            pruned = renderer.render(scene.subset(keep), cam)
            assert math.isclose(row["gt_psnr"], psnr(photo, pruned), rel_tol=1e-9)
            assert math.isclose(row["psnr"], psnr(renderer.render(scene, cam), pruned), rel_tol=1e-9)

    out = tmp_path / "out"
    from harness.report.outputs import publish
    from harness.report.record import copy_images

    copy_images(res.images, out)
    written = publish(out, df, {}, tables=["comparison", "photos"], plots=["photos"]).written
    assert not written.missing
    text = (out / "tables" / "photos-real.md").read_text()
    assert "held-out views: real" in text and "PSNR vs photo" in text and "| unpruned |" in text
    assert "PSNR vs photo" in (out / "tables" / "comparison-real.md").read_text()
    assert not (out / "tables" / "photos.md").exists()  # the rig's views have no photos
    assert {p.name for p in (out / "images" / "s" / "real").iterdir()} >= {"photo.png", "input.png"}
    assert (out / "plots" / "photos-s.png").is_file()


def test_rerun_hits_and_a_changed_photo_recomputes_only_what_it_touches(world):
    tmp_path, _, _, capture = world
    cfg = config(tmp_path, capture, ["rig", "real"])
    _, before = run(cfg, tmp_path)
    res, _ = run(cfg, tmp_path)
    assert sum(c["misses"] for c in res.counts.values()) == 0
    photo = tmp_path / "cap" / "photos" / "img2.png"
    Image.fromarray(np.zeros((48, 64, 3), np.uint8)).save(photo)
    fakes.CALLS.clear()
    res, df = run(cfg, tmp_path)
    assert res.counts["render_ref"]["misses"] == 0 and res.counts["score"]["misses"] == 0
    assert res.counts["gt"]["misses"] == 1 and res.counts["metrics"]["misses"] == 4  # img2's 4 pruned sets
    key = ["method", "ratio", "view"]
    old, new = (d[d["protocol"] == "real"].set_index(key).sort_index() for d in (before, df))
    changed = (old["gt_psnr"] != new["gt_psnr"]) | (old["unpruned_gt_psnr"] != new["unpruned_gt_psnr"])
    assert set(changed[changed].index.get_level_values("view")) == {"real/img2"}
    assert old["psnr"].equals(new["psnr"])  # pruned vs unpruned does not depend on the photo


def test_real_alone_measures_no_rig_view_and_skips_a_scene_without_capture(world):
    tmp_path, _, _, capture = world
    write_scene(random_scene(100, sh_degree=0, seed=5), tmp_path / "o.ply")
    cfg = config(tmp_path, capture, [{"name": "real", "n_test": 2}],
                 extra_scene={"name": "o", "source": str(tmp_path / "o.ply")})
    fakes.CALLS.clear()
    res, df = run(cfg, tmp_path)
    ok = df[df["status"] == "ok"]
    assert set(ok["protocol"]) == {"real"} and sorted(set(ok["view"])) == ["real/img0", "real/img2"]
    assert fakes.CALLS["score:fake-aware"] == 1  # only the capture's training set is needed
    skip = df[df["scene"] == "o"]
    assert len(skip) == 1 and "carries no capture" in skip["reason"].iloc[0]


def test_config_capture_and_real_protocol_errors(world):
    from harness.core.errors import InputError

    tmp_path, _, _, capture = world
    with pytest.raises(InputError, match=r"scenes\[0\].capture: give the held-out views once"):
        config(tmp_path, {**capture, "test_every": 8}, ["rig", "real"])
    with pytest.raises(InputError, match=r"protocols\[1\]: unknown view protocol 'reall' \(did you mean 'real'\?\)"):
        config(tmp_path, capture, ["rig", "reall"])
    with pytest.raises(InputError, match=r"protocols\[1\].n_test"):
        config(tmp_path, capture, ["rig", {"name": "real", "n_test": 0}])
    with pytest.raises(InputError, match=r"protocol.metrics\[0\]: unknown metric or metric set 'gt_psnr'"):
        parse_config({"scenes": ["s"], "methods": ["opacity"], "protocol": {"metrics": ["gt_psnr"]}}, "x.yaml")
