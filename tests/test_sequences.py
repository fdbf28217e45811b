"""MPEG content layouts end to end, without MPEG data: a synthetic sequence built here in the exact
CTC layout (``m71763_<seq>_stable/track/frame%03d.ply`` + ``colmap_data/frame000/sparse/``), one in the
``plys/`` layout with gsTools header cameras, found, rendered at native size with all cameras, scored
with the MPEG set and sized in bytes; absent content is a clean skip."""

from __future__ import annotations

import numpy as np
import pytest

from harness.core.cameras import Camera
from harness.io.cameras import ply_camera_comments
from harness.io.gscameras import quaternion
from harness.io.ply import write_ply
from harness.io.sequences import find_sequence, sequence_cameras
from harness.run.config import parse_config
from harness.run.runner import Runner
from tests.scene_factory import random_scene

W, H = 40, 30


def _cams():
    return [Camera.look_at((np.cos(a) * 4, 0.4, np.sin(a) * 4), (0, 0, 0), width=W, height=H, name=f"v{i:02d}.png")
            for i, a in enumerate(np.linspace(0.2, 1.4, 3))]


def write_colmap_txt(folder, cams):
    """COLMAP text model (PINHOLE), as colmap_data/frame000/sparse/ holds it."""
    folder.mkdir(parents=True)
    (folder / "cameras.txt").write_text("# Camera list\n" + "".join(
        f"{i + 1} PINHOLE {c.width} {c.height} {c.fx} {c.fy} {c.cx} {c.cy}\n" for i, c in enumerate(cams)))
    lines = ["# Image list"]
    for i, c in enumerate(cams):
        q, t = quaternion(c.rotation), c.translation
        lines += [f"{i + 1} {' '.join(repr(float(v)) for v in (*q, *t))} {i + 1} {c.name}", ""]
    (folder / "images.txt").write_text("\n".join(lines) + "\n")


@pytest.fixture
def content(tmp_path):
    root = tmp_path / "mpeg"
    stable = root / "m71763_toy_stable"
    (stable / "track").mkdir(parents=True)
    for f in range(2):
        write_ply(random_scene(300, 1, seed=f), stable / "track" / f"frame{f:03d}.ply")
    write_colmap_txt(stable / "colmap_data" / "frame000" / "sparse", _cams())
    other = root / "toy_plys" / "plys"
    other.mkdir(parents=True)
    write_ply(random_scene(200, 0, seed=5), other / "frame000.ply", comments=ply_camera_comments(_cams()))
    return root


def test_layouts_are_found(content):
    seq, why = find_sequence(content / "m71763_toy_stable")
    assert why is None and seq.layout == "track" and [p.name for p in seq.frames] == ["frame000.ply", "frame001.ply"]
    assert seq.cameras == content / "m71763_toy_stable" / "colmap_data" / "frame000" / "sparse"
    cams = sequence_cameras(seq)
    assert [(c.name, c.width, c.height, c.cx, c.cy) for c in cams] == [(f"v{i:02d}.png", W, H, W / 2, H / 2)
                                                                       for i in range(3)]
    for a, b in zip(_cams(), cams):
        np.testing.assert_allclose(a.world_to_cam, b.world_to_cam, atol=1e-9)
    seq2, _ = find_sequence(content / "toy_plys")
    assert seq2.layout == "plys" and seq2.cameras is None
    assert [c.width for c in sequence_cameras(seq2)] == [W] * 3  # the size line travels with the lines
    assert find_sequence(content / "missing")[0] is None


@pytest.mark.gl
def test_run_on_the_synthetic_sequence(content, tmp_path):
    doc = {"name": "seq", "protocol": {"metrics": ["psnr", "mpeg"], "renderer": "gl"},
           "ratios": [0.2, 0.4, 0.6], "anchor": "opacity",
           "scenes": [{"name": "toy", "sequence": str(content / "m71763_toy_stable")},
                      {"name": "toy_plys", "sequence": str(content / "toy_plys"), "test": ["v01.png"]},
                      {"name": "absent", "sequence": str(content / "m71763_absent_stable"), "optional": True}],
           "methods": ["opacity", "random"], "tables": ["bd", "ctc"], "plots": []}
    config = parse_config(doc, "seq.yaml")
    from harness.run import tasks

    try:
        result = Runner(config, out_dir=tmp_path / "out", cache_root=tmp_path / "cache", log=lambda m: None).run()
    except Exception as err:  # noqa: BLE001
        if "EGL" in str(err):
            pytest.skip(f"no EGL context: {err}")
        raise
    finally:  # the in-process worker state keeps a real GL renderer; later tests inject fakes
        renderer = tasks._STATE.get("renderer")
        if renderer is not None and hasattr(renderer, "close"):
            renderer.close()
        tasks._STATE.clear()
    assert not result.errors, result.errors
    assert [s.scene for s in result.skips] == ["absent"] and "not found" in result.skips[0].reason
    ok = [r for r in result.rows if r.get("status") == "ok"]
    toy = [r for r in ok if r["scene"] == "toy"]
    assert {r["frame"] for r in toy} == {"frame000", "frame001"}
    assert {r["view"] for r in toy} == {"v00.png", "v01.png", "v02.png"}  # every camera
    assert {(r["width"], r["height"]) for r in ok} == {(W, H)}  # native size
    assert {r["view"] for r in ok if r["scene"] == "toy_plys"} == {"v01.png"}
    for r in ok:
        assert r["bytes"] > r["splats_out"] * 56 and 0 < r["rgb_psnr"] <= 999.99 and "yuv_ssim_om" in r
    from harness.report.results import to_frame
    from harness.report.tables import build_tables

    tables = build_tables(to_frame(result.rows), ["bd", "ctc"], anchor="opacity")
    assert ("average", "Random") in tables["bd"].disp.index
    assert set(tables["ctc"].disp.index.get_level_values("RP")) == {"RP1", "RP2", "RP3"}
