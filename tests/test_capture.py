"""Captures (harness.io.capture, .photos, .similarity): transforms, photo matching and scaling, the
pinned bonsai capture against the mirror, fetching, and bad captures as one line with exit 2."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

from harness.cli import main
from harness.core.cameras import Camera
from harness.core.errors import InputError
from harness.io import capture as cap
from harness.io.cameras import write_3dgs_cameras
from harness.io.photos import read_photo
from harness.io.similarity import Similarity, parse_chain, parse_similarity, similarity_problem


def rotation(axis, angle) -> np.ndarray:
    """Rodrigues' formula, independent of the module under test."""
    a = np.asarray(axis, np.float64)
    a = a / np.linalg.norm(a)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def project(cam: Camera, x) -> tuple[np.ndarray, float]:
    p = cam.world_to_cam @ np.append(x, 1.0)
    return np.array([cam.fx * p[0] / p[2] + cam.cx, cam.fy * p[1] / p[2] + cam.cy]), p[2]


vec = st.lists(st.floats(-3, 3), min_size=3, max_size=3)


@settings(max_examples=60, deadline=None)
@given(axis=vec.filter(lambda v: np.linalg.norm(v) > 0.1), angle=st.floats(-3.1, 3.1), s=st.floats(0.2, 5.0),
       t=vec, eye=vec, point=st.lists(st.floats(-0.5, 0.5), min_size=3, max_size=3))
def test_a_similarity_moves_points_and_cameras_together(axis, angle, s, t, eye, point):
    """A point and a camera moved by the same similarity: same pixel, depth times s."""
    cam = Camera.look_at(np.asarray(eye) + [0, 0, 6.0], (0, 0, 0), width=64, height=48, name="c")
    sim = Similarity(rotation(axis, angle), s, np.asarray(t, np.float64))
    uv, z = project(cam, np.asarray(point))
    uv2, z2 = project(sim.camera(cam), sim.points(np.asarray(point)))
    assert np.allclose(uv, uv2, atol=1e-6) and math.isclose(z2, s * z, rel_tol=1e-9)
    moved = sim.camera(cam)
    assert np.allclose(moved.center, sim.points(cam.center)) and (moved.fx, moved.width) == (cam.fx, cam.width)


def test_a_chain_applies_in_order():
    a = Similarity(rotation((0, 0, 1), 0.7), 2.0, np.array([1.0, 0, 0]))
    b = Similarity(rotation((1, 0, 0), -0.3), 0.5, np.array([0, 2.0, 0]))
    x = np.array([0.3, -0.2, 0.9])
    assert np.allclose(a.then(b).points(x), b.points(a.points(x)))
    d = lambda m: {"R": m.R.tolist(), "s": m.s, "t": m.t.tolist()}  # noqa: E731
    assert np.allclose(parse_chain([d(a), d(b)], "x").points(x), b.points(a.points(x)))


@pytest.mark.parametrize("bad, phrase", [
    ({"R": [[1, 0.2, 0], [0, 1, 0], [0, 0, 1]], "s": 1, "t": [0, 0, 0]}, "not a rotation"),      # shear
    ({"R": [[2, 0, 0], [0, 1, 0], [0, 0, 1]], "s": 1, "t": [0, 0, 0]}, "non-uniform scale"),      # stretch
    ({"R": [[-1, 0, 0], [0, 1, 0], [0, 0, 1]], "s": 1, "t": [0, 0, 0]}, "reflection"),
    ({"R": np.eye(3).tolist(), "s": 0, "t": [0, 0, 0]}, "s must be a positive number"),
    ({"R": np.eye(3).tolist(), "s": 1}, "lacks t"),
    ({"R": np.eye(3).tolist(), "s": 1, "t": [0, "1", 0]}, "t must be 3 numbers"),
])
def test_what_is_not_a_similarity(bad, phrase):
    assert phrase in similarity_problem(bad)
    with pytest.raises(InputError, match="transform is not a similarity"):
        parse_similarity(bad, "t.json")


# --------------------------------------------------------------------------- photos
def test_photos_are_area_averaged_to_the_render_size(tmp_path):
    rng = np.random.default_rng(0)
    px = rng.integers(0, 256, (40, 60, 3), dtype=np.uint8)
    Image.fromarray(px).save(tmp_path / "a.png")
    half = read_photo(tmp_path / "a.png", 30, 20)
    blocks = px.astype(np.float64).reshape(20, 2, 30, 2, 3).mean(axis=(1, 3)) / 255.0  # dense numpy truth
    assert np.allclose(half, blocks, atol=1e-5)
    assert np.array_equal(read_photo(tmp_path / "a.png", 60, 40), px.astype(np.float32) / np.float32(255))
    with pytest.raises(InputError, match="would be upsampled"):
        read_photo(tmp_path / "a.png", 120, 80)


# --------------------------------------------------------------------------- the pinned bonsai capture
def _mirror():
    root = cap.mirror_root("bonsai-capture")
    if not root.is_dir():
        pytest.skip(f"bonsai capture mirror absent ({root}); `harness fetch bonsai-capture` or ../shared/data")
    return root


@pytest.mark.data
@pytest.mark.parametrize("scene", ["bonsai-7k", "bonsai-7k-mini"])
def test_derived_cameras_equal_the_mirrors_cameras(scene):
    """Cameras = pinned COLMAP-frame file + the manifest's transform; the mirror ships them derived."""
    from harness.io.cameras import read_3dgs_cameras

    root = _mirror()
    c = cap.load_capture(cap.named_spec(scene))
    want = {x.name: x for x in read_3dgs_cameras(root / f"cameras_{scene}.json")}
    assert len(c.train) == 24 and len(c.test) == 37 and c.photo_size == (780, 520)
    for got in c.train + c.test:
        assert np.abs(got.world_to_cam - want[got.name].world_to_cam).max() < 1e-9


@pytest.mark.data
def test_manifest_pins_the_mirror_bytes_and_split():
    root = _mirror()
    m = cap.manifest("bonsai-capture")
    assert m["split"] == {k: v for k, v in json.loads((root / "split.json").read_text()).items() if k != "note"}
    assert "b20eca07b5fcec29c01b0e7475a1ef2860a62ea9" in m["base_url"] and "non-commercial" in m["license"]
    from harness.io.datasets import sha256_file

    for rel, (_, size, sha) in m["files"].items():
        assert (root / rel).stat().st_size == size and sha256_file(root / rel) == sha, rel


@pytest.mark.data
def test_a_damaged_copy_is_refused(tmp_path, monkeypatch):
    """Verify on use: a named capture whose photo changed is one line naming it and how to fix it."""
    import shutil

    root = _mirror()
    copy = tmp_path / "shared" / "bonsai_capture"
    shutil.copytree(root, copy)
    photo = copy / "images" / "test" / "DSCF5573.png"
    photo.chmod(0o644)
    data = bytearray(photo.read_bytes())
    data[-20] ^= 1
    photo.write_bytes(bytes(data))
    monkeypatch.setenv("HARNESS_SHARED_DATA", str(tmp_path / "shared"))
    monkeypatch.setenv("HARNESS_CACHE", str(tmp_path / "cache"))
    with pytest.raises(
        InputError, match=r"DSCF5573.png: sha256 .* differs from the pinned .*harness fetch bonsai-capture"
    ):
        cap.load_capture(cap.named_spec("bonsai-7k"))


@pytest.mark.data
def test_fetch_a_capture_from_the_origin_layout(tmp_path, monkeypatch):
    """Downloads go by the origin's paths (file:// stands in for the pinned URL), land verified and
    in the local layout; a second fetch only verifies."""
    import shutil

    root = _mirror()
    m = cap.manifest("bonsai-capture")
    origin = tmp_path / "origin"
    for rel, (src, _, _) in m["files"].items():
        (origin / src).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(root / rel, origin / src)
    monkeypatch.setenv("HARNESS_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("HARNESS_SHARED_DATA", str(tmp_path / "no-mirror"))
    from harness.io.fetch import fetch_capture

    logs = []
    assert fetch_capture("bonsai-capture", log=logs.append, base_url=origin.as_uri() + "/") == "fetched"
    assert "downloaded from file://" in logs[0] and "non-commercial" in logs[0]
    assert cap.capture_root("bonsai-capture") == tmp_path / "cache" / "data" / "bonsai_capture"
    assert len(cap.load_capture(cap.named_spec("bonsai-7k")).photos) == 37
    assert fetch_capture("bonsai-capture", log=logs.append) == "present"


# --------------------------------------------------------------------------- bad captures, through the CLI
def write_capture(folder, n=6, size=(64, 48), photo_size=None, names=None) -> dict:
    """A capture of ``n`` cameras around the origin with flat grey photos; returns the config mapping."""
    folder.mkdir(parents=True, exist_ok=True)
    cams = [Camera.look_at((5 * math.cos(i), 0.5, 5 * math.sin(i)), (0, 0, 0), width=size[0], height=size[1],
                           name=f"img{i}") for i in range(n)]
    write_3dgs_cameras(cams, folder / "cameras.json")
    (folder / "photos").mkdir(exist_ok=True)
    for i, name in enumerate(names or [c.name for c in cams]):
        Image.new("RGB", photo_size or size, (40 * i, 90, 120)).save(folder / "photos" / f"{name}.png")
    (folder / "split.json").write_text(json.dumps({"test": ["img0", "img2", "img4"], "train": ["img1", "img3"]}))
    return {"cameras": str(folder / "cameras.json"), "images": str(folder / "photos"),
            "split": str(folder / "split.json")}


def run_config(tmp_path, capture: dict) -> dict:
    from harness.io.scenes import write_scene
    from tests.scene_factory import random_scene

    write_scene(random_scene(200, sh_degree=0, seed=3), tmp_path / "s.ply")
    return {"name": "bad", "output": str(tmp_path / "out"), "protocol": {"longest_side": 32, "metrics": ["psnr"]},
            "protocols": ["real"], "ratios": [0.3], "methods": ["opacity"], "tables": [], "plots": [],
            "scenes": [{"name": "s", "source": str(tmp_path / "s.ply"), "capture": capture}]}


def rejected(capsys, tmp_path, doc, *phrases) -> str:
    import yaml

    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(doc))
    for command in (["plan", str(cfg)], ["run", str(cfg), "--cache", str(tmp_path / "cache")]):
        rc = main(command)
        out, err = capsys.readouterr()
        lines = err.strip().splitlines()
        assert rc == 2 and len(lines) == 1 and "Traceback" not in err, (command, err)
        assert all(p in lines[0] for p in phrases), lines[0]
    assert not (tmp_path / "out").exists()  # nothing written
    return lines[0]


def test_camera_names_that_match_no_photo(capsys, tmp_path):
    c = write_capture(tmp_path / "cap", names=[f"DSC_{i:04d}" for i in range(6)])
    rejected(
        capsys,
        tmp_path,
        run_config(tmp_path, c),
        "cameras.json",
        "camera names (img0, img2, img4, ...) match no photo",
        "DSC_0000",
    )


def test_a_held_out_camera_without_its_photo(capsys, tmp_path):
    c = write_capture(tmp_path / "cap")
    (tmp_path / "cap" / "photos" / "img4.png").unlink()
    rejected(capsys, tmp_path, run_config(tmp_path, c), "photos: no photo for 1 held-out camera(s)", "img4")


def test_a_photo_of_another_aspect(capsys, tmp_path):
    c = write_capture(tmp_path / "cap")
    Image.new("RGB", (64, 64), (0, 0, 0)).save(tmp_path / "cap" / "photos" / "img2.png")
    rejected(capsys, tmp_path, run_config(tmp_path, c), "img2.png: photo is 64x64 (aspect 1.000)",
             "camera 'img2' is 64x48 (aspect 1.333)")


def test_a_photo_at_another_scale(capsys, tmp_path):
    c = write_capture(tmp_path / "cap")
    Image.new("RGB", (32, 24), (0, 0, 0)).save(tmp_path / "cap" / "photos" / "img4.png")
    rejected(capsys, tmp_path, run_config(tmp_path, c), "img4.png: photo is 32x24", "share one scale")


def test_a_split_naming_unknown_views(capsys, tmp_path):
    c = write_capture(tmp_path / "cap")
    (tmp_path / "cap" / "split.json").write_text(json.dumps({"test": ["img0", "imgg2"], "train": ["img1"]}))
    rejected(capsys, tmp_path, run_config(tmp_path, c), "split.json: names 1 view(s) the camera file does not have",
             "'imgg2' (did you mean 'img2'")


def test_a_transform_that_is_not_a_similarity(capsys, tmp_path):
    c = write_capture(tmp_path / "cap")
    (tmp_path / "t.json").write_text(json.dumps({"R": [[1, 0, 0], [0, 2, 0], [0, 0, 1]], "s": 1.0, "t": [0, 0, 0]}))
    rejected(capsys, tmp_path, run_config(tmp_path, {**c, "transform": str(tmp_path / "t.json")}),
             "t.json: transform is not a similarity: R is not a rotation")


def test_a_good_capture_loads(tmp_path):
    c = write_capture(tmp_path / "cap", size=(640, 480), photo_size=(160, 120))
    spec = cap.CaptureSpec(c["cameras"], c["images"], split=c["split"])
    got = cap.load_capture(spec)
    assert [x.name for x in got.test] == ["img0", "img2", "img4"] and [x.name for x in got.train] == ["img1", "img3"]
    train, test, side = cap.protocol_views(got, 2, 384)
    assert side == 160 and [x.name for x in test] == ["img0", "img2"]  # capped at the photos' size (the run names
    # them real/img0 ...: harness.run.protocol_views)
    assert (test[0].width, test[0].height) == (160, 120) and len(train) == 2


def test_fetching_a_scene_brings_its_capture_and_only_a_named_capture_can_fail_the_command(monkeypatch, capsys):
    from harness.io import fetch

    calls = []
    monkeypatch.setattr(fetch, "fetch_scenes", lambda names, **kw: calls.append(("scene", *names)))

    def no_network(name, **kw):
        calls.append(("capture", name))
        raise InputError(name, "download failed (no network)")

    monkeypatch.setattr(fetch, "fetch_capture", no_network)
    assert main(["fetch", "bonsai-7k", "bonsai-7k-mini"]) == 0  # brought along: reported, not fatal
    assert calls == [("scene", "bonsai-7k"), ("capture", "bonsai-capture"), ("scene", "bonsai-7k-mini")]
    assert "bonsai-capture: not fetched: bonsai-capture: download failed" in capsys.readouterr().out
    assert main(["fetch", "bonsai-capture"]) == 1  # asked for by name
