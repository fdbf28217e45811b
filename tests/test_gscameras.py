"""gsTools ``camera_position`` header lines: syntax, pose convention (COLMAP world-to-camera quaternion,
camera centre, OpenCV axes, K = [[f_y, 0, W/2], [0, f_y, H/2]]), round trip against a cameras.json,
placement before ``format`` in every PLY the harness writes (pruning included), clear errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from harness.cli import main
from harness.core.cameras import Camera
from harness.core.errors import InputError
from harness.io.cameras import (
    load_cameras,
    ply_camera_comments,
    read_3dgs_cameras,
    read_ply_cameras,
)
from harness.io.gscameras import (
    TOOL_SIZE,
    camera_lines,
    cameras_from_lines,
    quaternion,
    rotmat,
)
from harness.io.ply import read_ply_header, write_ply
from tests.scene_factory import random_scene


def colmap_qvec2rotmat(q):
    """COLMAP's scripts/python/read_write_model.py qvec2rotmat, written out here."""
    w, x, y, z = q
    return np.array([[1 - 2 * y ** 2 - 2 * z ** 2, 2 * x * y - 2 * w * z, 2 * z * x + 2 * w * y],
                     [2 * x * y + 2 * w * z, 1 - 2 * x ** 2 - 2 * z ** 2, 2 * y * z - 2 * w * x],
                     [2 * z * x - 2 * w * y, 2 * y * z + 2 * w * x, 1 - 2 * x ** 2 - 2 * y ** 2]])


def _head(path) -> list[str]:
    text = path.read_bytes().split(b"end_header\n")[0].decode("ascii")
    return text.splitlines()


def test_hand_case_matches_colmap_and_the_tools_intrinsics():
    q = np.array([0.9, 0.1, -0.3, 0.2])
    q /= np.linalg.norm(q)
    t = np.array([0.4, -1.2, 3.0])                 # COLMAP tvec: world -> camera
    r = colmap_qvec2rotmat(q)
    centre = -r.T @ t                               # what gsTools stores as pos
    line = ("camera_position        7        1" + "".join(f" {v:16.10f}" for v in [*centre, *q, 1500.0, 1400.0])
            + "         cam_007")
    (cam,) = cameras_from_lines([line], "x", 1920, 1080)
    np.testing.assert_allclose(cam.world_to_cam[:3, :3], r, atol=1e-9)
    np.testing.assert_allclose(cam.world_to_cam[:3, 3], t, atol=1e-9)
    assert (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height, cam.name) == (1400.0, 1400.0, 960.0, 540.0,
                                                                                 1920, 1080, "cam_007")
    # OpenCV axes: a point straight ahead of the camera (+z) lands on the image centre
    p = centre + r.T @ np.array([0.0, 0.0, 5.0])
    x, y, z, _ = cam.world_to_cam @ np.r_[p, 1.0]
    assert z == pytest.approx(5.0) and (cam.fx * x / z + cam.cx, cam.fy * y / z + cam.cy) == pytest.approx((960, 540))
    np.testing.assert_allclose(rotmat(quaternion(r)), r, atol=1e-12)


def test_round_trip_against_a_cameras_json(tmp_path):
    recs = []
    rng = np.random.default_rng(2)
    for i in range(6):
        cam = Camera.look_at(rng.normal(size=3) * 3, rng.normal(size=3) * 0.1, fov_y_deg=45 + 3 * i, width=1920,
                             height=1080, name=f"v{i:02d}")
        recs.append({"id": i, "img_name": cam.name, "width": 1920, "height": 1080, "position": cam.center.tolist(),
                     "rotation": cam.rotation.T.tolist(), "fx": cam.fx, "fy": cam.fy})
    (tmp_path / "cameras.json").write_text(json.dumps(recs))
    cams = read_3dgs_cameras(tmp_path / "cameras.json")
    write_ply(random_scene(20), tmp_path / "s.ply", comments=["made by a test", *ply_camera_comments(cams)])
    back = read_ply_cameras(tmp_path / "s.ply")
    assert len(back) == len(cams)
    for a, b in zip(cams, back):
        np.testing.assert_allclose(a.world_to_cam, b.world_to_cam, atol=1e-8)
        assert (a.fx, a.fy, a.cx, a.cy, a.width, a.height, a.name) == pytest.approx(
            (b.fx, b.fy, b.cx, b.cy, b.width, b.height, b.name), abs=1e-9)
    assert load_cameras(tmp_path / "s.ply")[3].name == "v03"
    assert [c.width for c in read_ply_cameras(tmp_path / "s.ply", 1024, 576)] == [1024] * 6  # the tool's --width


def test_lines_sit_before_format_in_gstools_syntax(tmp_path):
    cams = [Camera.look_at((0, 0, -3), (0, 0, 0), width=64, height=48, name="front view")]
    write_ply(random_scene(5), tmp_path / "s.ply", comments=["after", *ply_camera_comments(cams)])
    head = _head(tmp_path / "s.ply")
    fmt = head.index("format binary_little_endian 1.0")
    assert head[1].startswith("comment camera_position_header  imageId cameraId            pos.x")
    assert head[2].startswith("comment camera_position        1        1 ") and head[2].endswith(" front_view")
    assert fmt == 4 and head[fmt + 1] == "comment after"
    tokens = head[2].split()[2:]  # what the metric tool's `ss >> ...` reads: 12 tokens after the key
    assert len(tokens) == 12 and tokens[-1] == "front_view"
    assert read_ply_header(tmp_path / "s.ply").preamble[:2] == [head[1][8:], head[2][8:]]


def test_pruning_keeps_camera_lines_before_format(tmp_path):
    """A file whose camera_position lines stand after `format` (a careless writer) comes out of
    `harness prune` with them before it; an MPEG-conformant file keeps its header as it was."""
    cams = [Camera.look_at((np.cos(a) * 4, 0.3, np.sin(a) * 4), (0, 0, 0), width=80, height=60, name=f"c{i}")
            for i, a in enumerate(np.linspace(0, 6, 4))]
    lines = ply_camera_comments(cams)
    src = tmp_path / "src.ply"
    write_ply(random_scene(200), src, preamble=[], comments=["x"])
    raw = src.read_bytes().replace(b"comment x\n", b"comment x\n" + b"".join(b"comment " + c.encode() + b"\n"
                                                                             for c in lines))
    src.write_bytes(raw)
    assert read_ply_header(src).preamble == []  # really after `format` here
    assert main(["prune", str(src), str(tmp_path / "p.ply"), "--ratio", "0.3", "--method", "opacity"]) == 0
    head = _head(tmp_path / "p.ply")
    assert head.index("format binary_little_endian 1.0") == 1 + len(lines)
    for a, b in zip(cams, read_ply_cameras(tmp_path / "p.ply")):
        np.testing.assert_allclose(a.world_to_cam, b.world_to_cam, atol=1e-8)


def test_size_defaults_and_reference_syntax():
    # a header as the TMCV python writer makes it ("{:>8d} " ... trailing space), no size line
    text = ("camera_position        1        1     0.0000000000     0.0000000000    -4.0000000000"
            "     1.0000000000     0.0000000000     0.0000000000     0.0000000000  1000.0000000000"
            "  1000.0000000000         img_0001 ")
    (cam,) = cameras_from_lines(["camera_position_header  imageId cameraId", text], "f")
    assert (cam.width, cam.height) == TOOL_SIZE and cam.name == "img_0001"
    np.testing.assert_allclose(cam.world_to_cam[:3, 3], [0, 0, 4])


@pytest.mark.parametrize("line, match", [
    ("camera_position 1 1 0 0 0 1 0 0 0 1000 1000", "11 of the 12 fields"),
    ("camera_position 1 1 0 0 zero 1 0 0 0 1000 1000 n", "non-numeric"),
    ("camera_position 1 1 0 0 0 2 0 0 0 1000 1000 n", "quaternion norm"),
    ("camera_position 1 1 0 0 0 1 0 0 0 -5 1000 n", "focal lengths"),
    ("camera_position 1 1 0 0 nan 1 0 0 0 1000 1000 n", "non-finite"),
])
def test_unreadable_line_is_a_clear_error(tmp_path, line, match):
    (tmp_path / "bad.ply").write_text(f"ply\ncomment {line}\nformat ascii 1.0\nend_header\n")
    with pytest.raises(InputError, match=match):
        load_cameras(tmp_path / "bad.ply")


def test_writer_refuses_what_the_syntax_cannot_hold():
    c = Camera.look_at((0, 0, -3), (0, 0, 0), width=64, height=48)
    with pytest.raises(ValueError, match="off the image centre"):
        camera_lines([Camera(c.world_to_cam, c.fx, c.fy, 10.0, 20.0, 64, 48)])
    with pytest.raises(ValueError, match="one image size"):
        camera_lines([c, Camera.look_at((0, 0, -3), (0, 0, 0), width=32, height=48)])
