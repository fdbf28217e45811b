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
from harness.views import mpeg_viewpoints as vp
from renderers.reference import ReferenceRenderer
from tests import mpeg_reference as ref
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


def test_rows_equal_the_independent_reference_in_view_order(files, capsys):
    """Every printed value (metrics overlapped with rendering, computed only where the renders
    differ) is the independent re-statement's of the same renders, view by view, in order."""
    src, dst, a_scene, b_scene = files
    status, out, err = _run(capsys, src, dst, "--renderer", "reference", "--json")
    assert status == 0, err
    views = json.loads(out)["views"]
    r = ReferenceRenderer(device="cpu")
    keys = {"rgb_psnr": "psnr_rgb_avg", "yuv_psnr": "psnr_yuv_avg", "yuv_ssim": "ssim_avg",
            "rgb_psnr_om": "psnr_rgb_om_avg", "yuv_psnr_om": "psnr_yuv_om_avg", "yuv_ssim_om": "ssim_om_avg",
            "rgb_ivssim": "rgb_ivssim", "yuv_ivssim": "yuv_ivssim", "occupancy": "occupancy"}
    assert [row["view"] for row in views] == [c.name for c in _cams()]
    for cam, row in zip(_cams(), views):
        a, al = r.render_with_alpha(a_scene, cam)
        b, bl = r.render_with_alpha(b_scene, cam)
        want = ref.mpeg_metrics(ref.quantize_render_to_u8(a), ref.quantize_render_to_u8(b), occupancy_mask(al, bl))
        assert {k: row[k] for k in keys} == {k: want[v] for k, v in keys.items()}


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
    assert (
        status == 0 and "3 cameras from source PLY header, 48x36" in out and out.splitlines()[-1].split()[0] == "mean"
    )
    write_ply(scene, tmp_path / "bare.ply")
    status, out, _ = _run(capsys, tmp_path / "bare.ply", tmp_path / "bare.ply", "--renderer", "reference",
                          "--width", 16, "--height", 12)
    assert status == 0 and ("16 cameras from mpeg-gsc-metrics' own viewpoints (-n 16, its default: no PLY header "
                            "has camera_position lines): radius-5 sphere") in out
    write_ply(scene, tmp_path / "other.ply", comments=ply_camera_comments(_cams()[:2]))
    status, _, err = _run(capsys, src, tmp_path / "other.ply", "--renderer", "reference")
    assert status == 2 and "differ" in err
    assert _run(capsys, src, dst, "--width", 10)[0] == 2


# ------------------------------------------------------------------ viewpoints placed as the tool's -n N
def _gl_view(cam):
    """Our OpenCV world_to_cam as the tool's OpenGL view matrix (y and z negated)."""
    return np.diag([1.0, -1.0, -1.0, 1.0]) @ cam.world_to_cam


@pytest.mark.parametrize("n", [1, 2, 3, 7, 16, 40])
@pytest.mark.parametrize("centre", [(0.3, -1.2, 2.5), (-40.0, 3.0, 0.01), (1e-3, 0.0, 0.0)])
def test_placement_equals_the_tool_formula(n, centre):
    cams = [vp.look_at(eye, centre, up, 1024, 768) for eye, up in vp.tool_poses(n, centre)]
    want = ref.tool_viewpoints(n, centre)
    assert len(cams) == len(want) == n
    for cam, (pos, view, up, focal) in zip(cams, want):
        scale = max(1.0, float(np.abs(pos).max()))
        assert np.allclose(cam.center, pos, rtol=0, atol=2e-6 * scale)  # float32 tool vs float64 here
        assert np.allclose(_gl_view(cam), ref.tool_view_matrix(pos, view, up), rtol=0, atol=2e-5 * scale)
        assert (cam.fx, cam.fy, cam.cx, cam.cy) == (focal[0], focal[1], 512.0, 384.0)


def test_placement_hand_checked():
    # N = 1: eye = c + (5, 0, 0) looking along -x, up +y: right (OpenCV x) = -z, down = -y
    (cam,), c = vp.tool_viewpoints(np.array([[0, 2, 3], [2, 2, 3]], np.float32), 1)
    assert c.tolist() == [1, 2, 3] and cam.center.tolist() == [6, 2, 3]
    assert np.allclose(cam.rotation, [[0, 0, -1], [0, -1, 0], [-1, 0, 0]])
    # N = 2 around c = (1, 0, 0): the poles z = +-1 (r = 0), up = y (c is perpendicular to y)
    cams, _ = vp.tool_viewpoints(np.array([[0, 0, 0], [2, 0, 0]], np.float32), 2)
    assert cams[0].center.tolist() == [1, 0, 5] and cams[1].center.tolist() == [1, 0, -5]
    assert np.allclose(cams[0].rotation, [[1, 0, 0], [0, -1, 0], [0, 0, -1]])
    assert np.allclose(cams[1].rotation, [[-1, 0, 0], [0, -1, 0], [0, 0, 1]])
    # N = 3: the middle one on the equator at the golden angle 2.39996 rad, every camera looks at c
    cams, c = vp.tool_viewpoints(np.array([[0, 0, 0], [2, 0, 0]], np.float32), 3)
    phi = np.pi * (3 - np.sqrt(5))
    assert np.allclose(cams[1].center, c + 5 * np.array([np.cos(phi), np.sin(phi), 0.0]))
    for cam in cams:
        assert np.allclose(cam.forward, (c - cam.center) / 5.0)


def test_centre_on_the_y_axis_is_refused(tmp_path, capsys):
    scene = random_scene(50, 0, seed=1)
    scene = scene.subset(np.arange(len(scene)))
    scene.means[:] = scene.means - vp.box_centre(scene.means) + np.array([0.0, 1.5, 0.0])  # centre (0, 1.5, 0)
    write_ply(scene, tmp_path / "y.ply")
    status, _, err = _run(capsys, tmp_path / "y.ply", tmp_path / "y.ply", "-n", 4, "--renderer", "reference")
    assert status == 2 and "lies on the y axis" in err and "--cameras" in err
    assert _run(capsys, tmp_path / "y.ply", tmp_path / "y.ply", "-n", 1, "--renderer", "reference",
                "--width", 8, "--height", 8)[0] == 0  # one viewpoint needs no up vector


def test_views_flag_scores_the_placed_viewpoints(files, capsys):
    src, dst, a_scene, b_scene = files  # the header cameras are ignored when -n is given, as in the tool
    status, out, err = _run(
        capsys, src, dst, "-n", 3, "--renderer", "reference", "--json", "--width", 40, "--height", 30
    )
    assert status == 0, err
    obj = json.loads(out)
    assert obj["cameras"].startswith("mpeg-gsc-metrics' own viewpoints (-n 3): radius-5 sphere")
    cams, _ = vp.tool_viewpoints(a_scene.means, 3, 40, 30)
    r = ReferenceRenderer(device="cpu")
    for cam, row in zip(cams, obj["views"]):
        a, al = r.render_with_alpha(a_scene, cam)
        b, bl = r.render_with_alpha(b_scene, cam)
        want = tool_metrics(a, b, occupancy_mask(al, bl))
        assert row["view"] == cam.name and row["rgb_psnr"] == want["rgb_psnr"]
        assert row["rgb_ivssim"] == want["rgb_ivssim"] and row["yuv_ivssim"] == want["yuv_ivssim"]
    assert _run(capsys, src, dst, "-n", 0)[0] == 2
    with pytest.raises(SystemExit) as info:  # one source of viewpoints
        _run(capsys, src, dst, "-n", 2, "--cameras", src)
    assert info.value.code == 2 and "not allowed with" in capsys.readouterr().err


def test_a_smaller_window_is_said_to_crop(files, capsys):
    src, dst, _, _ = files
    status, out, _ = _run(capsys, src, dst, "--renderer", "reference", "--width", 24, "--height", 18)
    assert status == 0 and "window 24x18: the centre crop of each 48x36 view" in out and "not scaled" in out
    status, out, _ = _run(capsys, src, dst, "--renderer", "reference", "--json", "--width", 24, "--height", 18)
    assert "centre crop" in json.loads(out)["window"]
    status, out, _ = _run(capsys, src, dst, "--renderer", "reference", "--width", 48, "--height", 36)
    assert "crop" not in out
