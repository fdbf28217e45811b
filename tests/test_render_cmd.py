"""`harness render` end to end with the reference renderer on a tiny scene at low resolution."""

from __future__ import annotations

import json

import numpy as np
import pytest

from harness.cli import main
from harness.io.cameras import load_cameras, write_3dgs_cameras
from harness.views.contact_sheet import coverage, to_uint8
from tests.scene_factory import random_scene

reference = pytest.importorskip(
    "renderers.reference", reason="the reference renderer (renderers/reference.py) is not importable"
)


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    from harness.io.ply import write_ply

    path = tmp_path_factory.mktemp("scene") / "tiny.ply"
    scene = random_scene(150, sh_degree=1, seed=4)
    scene.scales_log[:] -= 1.0  # std-devs ~ 0.7 % of the cloud: small splats, some background visible
    write_ply(scene, path)
    return path


def run(*argv) -> int:
    return main(["render", *map(str, argv)])


def test_rig_npy_matches_a_direct_render(scene_file, tmp_path, capsys):
    out = tmp_path / "out"
    assert run(scene_file, "--rig", "orbit", "--out", out, "--backend", "reference", "--format", "npy",
               "--longest-side", 40, "--n-train", 3, "--n-test", 2, "--background", "0.2,0.3,0.4") == 0
    files = sorted(p.name for p in out.iterdir())
    assert files == ["000_orbit_001.npy", "001_orbit_003.npy", "cameras.json", "contact_sheet.png", "coverage.json"]
    cams = load_cameras(out / "cameras.json")
    assert [c.name for c in cams] == ["orbit_001", "orbit_003"]  # the held-out views of 5
    from harness.io.scenes import load_scene

    scene = load_scene(scene_file)
    renderer = reference.ReferenceRenderer(device="cpu")
    record = json.loads((out / "coverage.json").read_text())
    for cam, name, rec in zip(cams, files[:2], record):
        img = np.load(out / name)
        assert img.dtype == np.float32 and img.shape == (cam.height, cam.width, 3) and max(img.shape) == 40
        np.testing.assert_allclose(img, renderer.render(scene, cam, background=(0.2, 0.3, 0.4)), atol=1e-6)
        assert rec["coverage"] == pytest.approx(coverage(img, (0.2, 0.3, 0.4)), abs=1e-4)
        assert 0.05 < rec["coverage"] < 1.0
    first = capsys.readouterr().out.splitlines()[0]
    assert first.startswith("orbit_001  40x") and "coverage" in first  # the view's name first, no blank column


def test_camera_file_png_split(scene_file, tmp_path):
    from PIL import Image

    from harness.core.cameras import Camera

    cams = [Camera.look_at((np.cos(a) * 5, 0.5, np.sin(a) * 5), (0, 0, 0), width=64, height=32, name=f"v{i}")
            for i, a in enumerate(np.linspace(0, 6, 10))]
    write_3dgs_cameras(cams, tmp_path / "cams.json")
    out = tmp_path / "png"
    assert run(scene_file, "--cameras", tmp_path / "cams.json", "--out", out, "--backend", "reference",
               "--longest-side", 32) == 0
    # a camera file is used as given: every camera (issue 23: "wrote 1 views" of an 8-camera file)
    assert len(list(out.glob("0*.png"))) == 10
    assert [c.name for c in load_cameras(out / "cameras.json")] == [c.name for c in cams]
    assert run(scene_file, "--cameras", tmp_path / "cams.json", "--out", tmp_path / "test", "--backend", "reference",
               "--longest-side", 32, "--split", "test") == 0
    pngs = sorted((tmp_path / "test").glob("*.png"))
    assert [p.name for p in pngs] == ["000_v0.png", "001_v8.png", "contact_sheet.png"]  # --split: every 8th view
    im = np.asarray(Image.open(pngs[1]))
    assert im.shape == (16, 32, 3) and im.dtype == np.uint8
    assert run(scene_file, "--cameras", tmp_path / "cams.json", "--out", tmp_path / "npy", "--backend",
               "reference", "--longest-side", 32, "--format", "npy", "--split", "test") == 0
    np.testing.assert_array_equal(im, to_uint8(np.load(tmp_path / "npy" / "001_v8.npy")))


@pytest.mark.parametrize("extra, message", [
    (["--rig", "orbit", "--background", "1,2"], "--background"),
    (["--cameras", "/nonexistent/cams.json"], "no such file"),
    (["--rig", "orbit", "--longest-side", "0"], "--longest-side"),
    (["--rig", "orbit", "--n-test", "0"], "--n-test"),
    (["--rig", "orbit", "--n-test", "10000"], "--n-test: must be a whole number from 1 to 1000"),
    (["--rig", "orbit", "--aspect", "0"], "--aspect"),
])
def test_bad_input_is_one_line_exit_2(scene_file, tmp_path, capsys, extra, message):
    out = tmp_path / "out"
    assert run(scene_file, "--out", out, "--backend", "reference", *extra) == 2
    err = capsys.readouterr().err
    assert err.startswith("harness: ") and message in err and err.count("\n") == 1
    assert not out.exists()  # nothing written


def test_missing_scene_and_file_as_out(tmp_path, capsys, scene_file):
    assert run(tmp_path / "nope.ply", "--rig", "orbit", "--out", tmp_path / "o", "--backend", "reference") == 2
    assert "harness: " in capsys.readouterr().err and not (tmp_path / "o").exists()
    (tmp_path / "file").write_text("x")
    assert run(scene_file, "--rig", "orbit", "--out", tmp_path / "file", "--backend", "reference") == 2
    assert "not a folder" in capsys.readouterr().err


def _rendered_cameras(out):
    return [c.to_dict() for c in load_cameras(out / "cameras.json")]


def test_views_never_come_from_the_file_name(scene_file, tmp_path):
    """The same flags give the same cameras whatever the file is called (luigi.ply vs luigi_pruned.ply)."""
    import shutil

    renamed = tmp_path / "luigi.ply"
    shutil.copyfile(scene_file, renamed)
    common = ("--rig", "orbit", "--backend", "reference", "--longest-side", 24, "--n-train", 2, "--n-test", 2)
    assert run(scene_file, "--out", tmp_path / "a", *common) == 0
    assert run(renamed, "--out", tmp_path / "b", *common) == 0
    assert _rendered_cameras(tmp_path / "a") == _rendered_cameras(tmp_path / "b")


def test_pruned_scene_renders_at_the_same_size(scene_file, tmp_path):
    """Explicit rig flags: a scene and its pruned copy render at the same size (compare works)."""
    assert main(["prune", str(scene_file), str(tmp_path / "p.ply"), "--ratio", "0.3", "--method", "opacity"]) == 0
    common = ("--rig", "orbit", "--backend", "reference", "--longest-side", 24, "--n-train", 2, "--n-test", 2)
    assert run(scene_file, "--out", tmp_path / "a", *common) == 0
    assert run(tmp_path / "p.ply", "--out", tmp_path / "b", *common) == 0
    sizes = [{(c["width"], c["height"]) for c in _rendered_cameras(tmp_path / d)} for d in "ab"]
    assert sizes[0] == sizes[1]
    # identical views: render the second scene with the first render's cameras (all of them, as given)
    assert run(tmp_path / "p.ply", "--out", tmp_path / "c", "--cameras", tmp_path / "a" / "cameras.json",
               "--backend", "reference") == 0
    for c, a in zip(_rendered_cameras(tmp_path / "c"), _rendered_cameras(tmp_path / "a"), strict=True):
        assert (c["name"], c["width"], c["height"]) == (a["name"], a["width"], a["height"])
        np.testing.assert_allclose(c["world_to_cam"], a["world_to_cam"], atol=1e-12)


def test_embedded_cameras_are_the_default_views(scene_file, tmp_path, capsys):
    from harness.core.cameras import Camera
    from harness.io.cameras import ply_camera_comments
    from harness.io.scenes import load_scene, write_scene

    cams = [Camera.look_at((np.cos(a) * 5, 0.5, np.sin(a) * 5), (0, 0, 0), width=30, height=20, name=f"e{i}")
            for i, a in enumerate(np.linspace(0, 2 * np.pi, 9, endpoint=False))]
    with_cams = tmp_path / "with_cams.ply"
    write_scene(load_scene(scene_file), with_cams, comments=ply_camera_comments(cams))
    assert run(with_cams, "--out", tmp_path / "o", "--backend", "reference", "--split", "all") == 0
    assert "embedded cameras" in capsys.readouterr().out
    assert [c["name"] for c in _rendered_cameras(tmp_path / "o")] == [c.name for c in cams]
    # pruning keeps them (header comments travel with the scene), so the pruned file renders the same views
    assert main(["prune", str(with_cams), str(tmp_path / "p.ply"), "--ratio", "0.5", "--method", "opacity"]) == 0
    assert run(tmp_path / "p.ply", "--out", tmp_path / "q", "--backend", "reference", "--split", "all") == 0
    assert _rendered_cameras(tmp_path / "q") == _rendered_cameras(tmp_path / "o")


def test_a_scene_pruned_from_a_dataset_renders_the_datasets_own_cameras(scene_file, tmp_path, monkeypatch, capsys):
    """Issue 23: `render luigi30.ply --rig default` (luigi pruned by 30 %) picked 1024x768 where `render
    luigi` picked 1024x1024 under the same view names. Sizes come from the flags only, and a scene
    pruned from a dataset is rendered from that dataset's rig, fitted to the dataset: the same cameras."""
    from types import SimpleNamespace

    from harness.io import datasets

    monkeypatch.setattr(datasets, "SCENES", {"tiny-set": SimpleNamespace(sha256=None)})
    monkeypatch.setattr(datasets, "scene_path", lambda name: scene_file)
    assert main(["prune", str(scene_file), str(tmp_path / "p30.ply"), "--ratio", "0.3", "--method", "opacity"]) == 0
    common = ("--backend", "reference", "--longest-side", 24, "--n-train", 2, "--n-test", 3)
    assert run("tiny-set", "--out", tmp_path / "a", *common) == 0
    assert run(tmp_path / "p30.ply", "--out", tmp_path / "b", *common) == 0
    assert "fitted to tiny-set: this scene's splats are a subset of it" in capsys.readouterr().out
    assert _rendered_cameras(tmp_path / "a") == _rendered_cameras(tmp_path / "b")
    assert {(c["width"], c["height"]) for c in _rendered_cameras(tmp_path / "a")} == {(24, 18)}  # 4/3 from the flags
    # an unrelated scene: its own auto rig, but the same sizes, so `compare` lines up
    other = tmp_path / "other.ply"
    from harness.io.ply import write_ply

    write_ply(random_scene(120, sh_degree=1, seed=9), other)
    assert run(other, "--out", tmp_path / "c", *common) == 0
    assert "subset" not in capsys.readouterr().out
    assert {(c["width"], c["height"]) for c in _rendered_cameras(tmp_path / "c")} == {(24, 18)}
    first = sorted((tmp_path / "a").glob("000_*.png"))[0].name
    assert main(["compare", str(tmp_path / "a" / first), str(sorted((tmp_path / "c").glob("000_*.png"))[0]),
                 "--metrics", "psnr"]) == 0


@pytest.mark.parametrize("overlap", [True, False])
def test_render_holds_one_image_at_a_time(scene_file, tmp_path, monkeypatch, overlap):
    """Renders are streamed to disk: when view k is rendered, at most view k - 1 is alive (being
    written meanwhile), and none when views are larger than the overlap allows (+590 MB per view
    at 8192 px)."""
    import weakref

    import renderers
    from harness.commands import render as render_cmd

    if not overlap:
        monkeypatch.setattr(render_cmd, "OVERLAP_MAX_BYTES", 0)
    alive = []

    class Fake:
        def render(self, scene, cam, background=(0, 0, 0)):
            alive.append(sum(r() is not None for r in refs))
            img = np.full((cam.height, cam.width, 3), 0.5, np.float32)
            refs.append(weakref.ref(img))
            return img

        def close(self):
            pass

    refs = []
    monkeypatch.setattr(renderers, "get_renderer", lambda backend, device=None: Fake())
    assert run(scene_file, "--rig", "orbit", "--out", tmp_path / "o", "--longest-side", 64, "--n-train", 0,
               "--n-test", 6) == 0
    assert len(alive) == 6 and max(alive) <= (1 if overlap else 0), alive
    assert len(list((tmp_path / "o").glob("0*.png"))) == 6
