"""Camera readers/writers: hand-computed projections per format, round trips, bad files.

Every hand case puts one world point at a known pixel: with fx = fy = 100, cx = 100, cy = 50 a point
at camera coordinates (1, 0.5, 5) lands at u = 100·1/5 + 100 = 120, v = 100·0.5/5 + 50 = 60.
"""

from __future__ import annotations

import json
import math
import struct

import numpy as np
import pytest

from harness.core.cameras import Camera
from harness.core.errors import InputError
from harness.io.cameras import (
    load_cameras,
    ply_camera_comments,
    read_3dgs_cameras,
    read_transforms_json,
    write_3dgs_cameras,
)
from harness.io.colmap import MODEL_IDS, read_colmap_model


def project(cam: Camera, p) -> tuple[float, float, float]:
    x, y, z, _ = cam.world_to_cam @ np.r_[np.asarray(p, float), 1.0]
    return cam.fx * x / z + cam.cx, cam.fy * y / z + cam.cy, z


def assert_same(a: Camera, b: Camera, tol=1e-9):
    np.testing.assert_allclose(a.world_to_cam, b.world_to_cam, atol=tol)
    assert (a.fx, a.fy, a.cx, a.cy, a.width, a.height, a.name) == pytest.approx(
        (b.fx, b.fy, b.cx, b.cy, b.width, b.height, b.name))


def random_cameras(n=5, seed=0):
    rng = np.random.default_rng(seed)
    cams = []
    for i in range(n):
        eye = rng.normal(size=3) * 4
        cam = Camera.look_at(eye, rng.normal(size=3) * 0.1, up=(0, -1, 0), fov_y_deg=40 + 10 * i,
                             width=320 + 16 * i, height=240, name=f"img_{i:03d}.png")
        cams.append(cam)
    # one with an off-centre principal point and fx != fy
    c = cams[-1]
    cams[-1] = Camera(c.world_to_cam, 310.0, 290.0, 150.5, 110.25, c.width, c.height, c.name)
    return cams


# ------------------------------------------------------------------------------ 3DGS cameras.json
def test_3dgs_hand_case_identity_and_rotated(tmp_path):
    recs = [
        {"id": 0, "img_name": "a", "width": 200, "height": 100, "position": [0, 0, -5],
         "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "fx": 100, "fy": 100},
        # camera at (5, 0, 0) looking along −x: camera axes x=(0,0,1), y=(0,1,0), z=(−1,0,0) are the
        # columns of the camera-to-world rotation
        {"id": 1, "img_name": "b", "width": 200, "height": 100, "position": [5, 0, 0],
         "rotation": [[0, 0, -1], [0, 1, 0], [1, 0, 0]], "fx": 100, "fy": 100},
    ]
    (tmp_path / "cameras.json").write_text(json.dumps(recs))
    a, b = read_3dgs_cameras(tmp_path / "cameras.json")
    assert project(a, (1, 0.5, 0)) == pytest.approx((120, 60, 5))
    assert project(b, (0, 0.5, 1)) == pytest.approx((120, 60, 5))
    np.testing.assert_allclose(b.center, [5, 0, 0], atol=1e-12)
    assert (a.cx, a.cy) == (100.0, 50.0)


def test_3dgs_round_trip(tmp_path):
    cams = random_cameras()
    write_3dgs_cameras(cams, tmp_path / "out" / "cameras.json")
    back = load_cameras(tmp_path / "out")  # folder dispatch
    for a, b in zip(cams, back):
        assert_same(a, b)
    data = json.loads((tmp_path / "out" / "cameras.json").read_text())
    assert set(data[0]) == {"id", "img_name", "width", "height", "position", "rotation", "fx", "fy"}
    assert data[-1]["cx"] == 150.5  # off-centre principal point kept in extra keys
    np.testing.assert_allclose(data[0]["position"], cams[0].center)


# ------------------------------------------------------------------------------ COLMAP
ROT_Y90 = (math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0)  # R = [[0,0,1],[0,1,0],[-1,0,0]]
COLMAP_CAMERAS = [(1, "PINHOLE", 200, 100, (100, 100, 100, 50)),
                  (2, "SIMPLE_RADIAL", 200, 100, (100, 100, 50, 0.01)),
                  (3, "OPENCV", 200, 100, (100, 100, 100, 50, 0.1, -0.02, 0.001, 0.002))]
# (image id, qvec, tvec, camera id, name, point that must land on (120, 60))
COLMAP_IMAGES = [(1, (1, 0, 0, 0), (0, 0, 5), 1, "b.png", (1, 0.5, 0)),
                 (2, ROT_Y90, (2, 0, 5), 2, "a.png", (0, 0.5, -1)),
                 (3, ROT_Y90, (2, 0, 5), 3, "c d.png", (0, 0.5, -1))]


def write_colmap_text(d, points_lines=True):
    d.mkdir(parents=True, exist_ok=True)
    lines = ["# Camera list", "# CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]"]
    lines += [f"{cid} {m} {w} {h} " + " ".join(map(str, p)) for cid, m, w, h, p in COLMAP_CAMERAS]
    (d / "cameras.txt").write_text("\n".join(lines) + "\n")
    lines = ["# Image list with two lines of data per image:"]
    for iid, q, t, cid, name, _ in COLMAP_IMAGES:
        lines.append(f"{iid} " + " ".join(map(str, (*q, *t))) + f" {cid} {name}")
        lines.append("10.5 20.5 -1 11.0 21.0 7" if points_lines else "")
    (d / "images.txt").write_text("\n".join(lines) + "\n")


def write_colmap_binary(d):
    """A COLMAP binary model written from the documented layout (independent of the reader)."""
    d.mkdir(parents=True, exist_ok=True)
    buf = struct.pack("<Q", len(COLMAP_CAMERAS))
    for cid, m, w, h, p in COLMAP_CAMERAS:
        buf += struct.pack("<iiQQ", cid, MODEL_IDS[m], w, h) + struct.pack(f"<{len(p)}d", *p)
    (d / "cameras.bin").write_bytes(buf)
    buf = struct.pack("<Q", len(COLMAP_IMAGES))
    for k, (iid, q, t, cid, name, _) in enumerate(COLMAP_IMAGES):
        buf += struct.pack("<I4d3dI", iid, *q, *t, cid) + name.encode() + b"\0"
        buf += struct.pack("<Q", k) + b"".join(struct.pack("<ddq", 1.0 * j, 2.0 * j, -1) for j in range(k))
    (d / "images.bin").write_bytes(buf)


@pytest.mark.parametrize("points_lines", [True, False])
def test_colmap_text_hand_cases(tmp_path, points_lines):
    write_colmap_text(tmp_path / "sparse" / "0", points_lines)
    cams = load_cameras(tmp_path)
    assert [c.name for c in cams] == ["a.png", "b.png", "c d.png"]  # sorted by name
    by_name = {c.name: c for c in cams}
    for _, _, _, _, name, p in COLMAP_IMAGES:
        assert project(by_name[name], p) == pytest.approx((120, 60, 5))


def test_colmap_binary_equals_text(tmp_path):
    write_colmap_text(tmp_path / "txt")
    write_colmap_binary(tmp_path / "bin")
    for a, b in zip(read_colmap_model(tmp_path / "txt"), load_cameras(tmp_path / "bin" / "images.bin")):
        assert_same(a, b)


def test_colmap_bad_files(tmp_path):
    write_colmap_binary(tmp_path / "m")
    raw = (tmp_path / "m" / "images.bin").read_bytes()
    (tmp_path / "m" / "images.bin").write_bytes(raw[:-7])
    with pytest.raises(InputError, match="truncated"):
        load_cameras(tmp_path / "m")
    write_colmap_text(tmp_path / "t")
    (tmp_path / "t" / "cameras.txt").write_text("1 WEIRD_MODEL 200 100 1 2 3\n")
    with pytest.raises(InputError, match="unknown COLMAP camera model"):
        load_cameras(tmp_path / "t")
    (tmp_path / "t" / "cameras.txt").write_text("1 PINHOLE 200 100 100 100 100\n")
    with pytest.raises(InputError, match="needs 4 parameters"):
        load_cameras(tmp_path / "t")


# ------------------------------------------------------------------------------ NeRF transforms.json
def test_transforms_opengl_flip(tmp_path):
    # OpenGL camera at (0, 0, 5) with identity rotation looks along −z with +y up. The point
    # (1, 0.5, 0) is 5 in front, right and *up*: in OpenCV (y down) it is at (1, −0.5, 5) -> v = 40.
    m = np.eye(4)
    m[:3, 3] = (0, 0, 5)
    data = {"fl_x": 100, "fl_y": 100, "cx": 100, "cy": 50, "w": 200, "h": 100,
            "frames": [{"file_path": "./r_0", "transform_matrix": m.tolist()}]}
    (tmp_path / "transforms.json").write_text(json.dumps(data))
    (cam,) = load_cameras(tmp_path / "transforms.json")
    assert project(cam, (1, 0.5, 0)) == pytest.approx((120, 40, 5))
    np.testing.assert_allclose(cam.forward, [0, 0, -1], atol=1e-12)


def test_transforms_camera_angle_and_image_size(tmp_path):
    from PIL import Image

    Image.new("RGB", (64, 48)).save(tmp_path / "r_0.png")
    angle = 2 * math.atan(32 / 40.0)  # fl = ½·64 / tan(½ angle) = 40
    data = {"camera_angle_x": angle, "frames": [{"file_path": "./r_0", "transform_matrix": np.eye(4).tolist()}]}
    (tmp_path / "transforms.json").write_text(json.dumps(data))
    (cam,) = read_transforms_json(tmp_path / "transforms.json")
    assert (cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy) == pytest.approx((64, 48, 40, 40, 32, 24))
    data["frames"][0]["file_path"] = "./missing"
    (tmp_path / "transforms.json").write_text(json.dumps(data))
    with pytest.raises(InputError, match="no w/h"):
        read_transforms_json(tmp_path / "transforms.json")


# ------------------------------------------------------------------------------ PLY header
def test_ply_header_cameras_round_trip(tmp_path):
    """Legacy ``comment camera {JSON}`` lines (earlier versions of this harness) are still read;
    the gsTools syntax it writes now is tested in test_gscameras.py."""
    import json

    from harness.io.ply import write_ply
    from tests.scene_factory import random_scene

    cams = random_cameras()
    legacy = ["camera " + json.dumps(c.to_dict()) for c in cams]
    write_ply(random_scene(10), tmp_path / "s.ply", comments=["made by a test", *legacy])
    head = (tmp_path / "s.ply").read_bytes()[:4000].decode("ascii", "replace")
    assert head.count("\ncomment camera {") == len(cams)
    for a, b in zip(cams, load_cameras(tmp_path / "s.ply")):
        assert_same(a, b, tol=1e-12)
    assert ply_camera_comments(cams[:1])[1].startswith("camera_position ")
    write_ply(random_scene(3), tmp_path / "plain.ply")
    with pytest.raises(InputError, match="no 'comment camera"):
        load_cameras(tmp_path / "plain.ply")


# ------------------------------------------------------------------------------ bad input
@pytest.mark.parametrize("content, match", [
    ("{not json", "not a readable JSON"),
    ("[]", "non-empty JSON list"),
    ('[{"width": 10}]', "lacks"),
    ('{"something": 1}', "neither"),
    (('[{"width": 10, "height": 10, "position": [0,0,0], "rotation": [[1,0,0],[0,2,0],[0,0,1]], '
     '"fx": 5, "fy": 5}]'), "not a proper orthonormal"),
    (('[{"width": 10, "height": 10, "position": [0,0,0], "rotation": [[1,0,0],[0,1,0],[0,0,1]], '
     '"fx": -5, "fy": 5}]'), "focal lengths must be positive"),
    (('[{"width": 10.5, "height": 10, "position": [0,0,0], "rotation": [[1,0,0],[0,1,0],[0,0,1]], '
     '"fx": 5, "fy": 5}]'), "positive integers"),
    (('{"frames": [{"file_path": "x", "w": 4, "h": 4, "transform_matrix": [[1,0,0,0],[0,1,0,0],'
     '[0,0,1,0],[0,0,0,1]]}]}'), "no focal length"),
])
def test_bad_json_files(tmp_path, content, match):
    (tmp_path / "c.json").write_text(content)
    with pytest.raises(InputError, match=match):
        load_cameras(tmp_path / "c.json")


def test_bad_paths(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_cameras(tmp_path / "nope.json")
    with pytest.raises(InputError, match="folder has no"):
        load_cameras(tmp_path)
    (tmp_path / "x.txt").write_text("hello")
    with pytest.raises(InputError, match="unknown camera file type"):
        load_cameras(tmp_path / "x.txt")
    (tmp_path / "bad.ply").write_text("ply\nformat ascii 1.0\ncomment camera {oops\nend_header\n")
    with pytest.raises(InputError, match="malformed camera comment"):
        load_cameras(tmp_path / "bad.ply")
