"""`harness score SOURCE PROCESSED`: same cameras for both, the tool's window/intrinsics, per-view tool
metrics on 8-bit renders with the union occupancy mask, the mean as the tool's getAverage."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest

from harness.cli import main
from harness.core.cameras import Camera
from harness.io.cameras import ply_camera_comments, write_3dgs_cameras
from harness.io.ply import write_ply
from harness.metrics.mpeg import occupancy_mask, tool_metrics
from renderers.reference import ReferenceRenderer
from tests.scene_factory import random_scene


def _cams(w=48, h=36):
    return [Camera.look_at((np.cos(a) * 4, 0.5, np.sin(a) * 4), (0, 0, 0), width=w, height=h, name=f"v{i}")
            for i, a in enumerate(np.linspace(0, 5, 3))]


@pytest.fixture
def files(tmp_path):
    scene = random_scene(400, 1, seed=3)
    src = tmp_path / "src.ply"
    write_ply(scene, src, comments=ply_camera_comments(_cams()))
    keep = np.random.default_rng(0).random(len(scene)) > 0.4
    dst = tmp_path / "dst.ply"
    write_ply(scene.subset(keep), dst, comments=ply_camera_comments(_cams()))
    return src, dst, scene, scene.subset(keep)


def _run(capsys, *argv):
    status = main(["score", *map(str, argv)])
    out, err = capsys.readouterr()
    return status, out, err


def test_json_matches_the_tool_metrics_of_the_renders(files, capsys):
    src, dst, a_scene, b_scene = files
    status, out, err = _run(capsys, src, dst, "--renderer", "reference", "--json", "--qmiv")
    assert status == 0, err
    obj = json.loads(out)
    assert obj["cameras"] == "source PLY header" and (obj["width"], obj["height"]) == (48, 36)
    assert obj["processed"]["splats"] == len(b_scene) and obj["mode"] == "qmiv"
    r = ReferenceRenderer(device="cpu")
    for cam, row in zip(_cams(), obj["views"]):
        a, al = r.render_with_alpha(a_scene, cam)
        b, bl = r.render_with_alpha(b_scene, cam)
        want = tool_metrics(a, b, occupancy_mask(al, bl), qmiv=True)
        assert row["view"] == cam.name
        for k in ("rgb_psnr", "yuv_psnr", "yuv_ssim", "rgb_psnr_om", "yuv_psnr_om", "yuv_ssim_om", "occupancy"):
            assert row[k] == want[k], k
    for k in ("rgb_psnr", "yuv_ssim_om"):
        acc = 0.0
        for row in obj["views"]:
            acc += row[k]
        assert obj["mean"][k] == acc / 3


def test_cameras_file_size_flags_and_csv(files, tmp_path, capsys):
    src, dst, _, _ = files
    write_3dgs_cameras(_cams(96, 72), tmp_path / "cams.json")
    status, out, err = _run(capsys, src, dst, "--renderer", "reference", "--csv", "--cameras", tmp_path / "cams.json",
                            "--width", 40, "--height", 30)
    assert status == 0, err
    rows = list(csv.DictReader(io.StringIO(out)))
    assert [r["view"] for r in rows] == ["v0", "v1", "v2", "mean"]
    assert float(rows[0]["rgb_psnr"]) < 999.99


def test_text_output_and_errors(files, tmp_path, capsys):
    src, dst, scene, _ = files
    status, out, _ = _run(capsys, src, dst, "--renderer", "reference")
    assert status == 0 and "3 cameras from source PLY header, 48x36" in out and out.splitlines()[-1].split()[0] == "mean"
    write_ply(scene, tmp_path / "bare.ply")
    assert _run(capsys, tmp_path / "bare.ply", tmp_path / "bare.ply")[2].count("no cameras") == 1
    write_ply(scene, tmp_path / "other.ply", comments=ply_camera_comments(_cams()[:2]))
    status, _, err = _run(capsys, src, tmp_path / "other.ply", "--renderer", "reference")
    assert status == 2 and "differ" in err
    assert _run(capsys, src, dst, "--width", 10)[0] == 2
