"""Malformed input -> one line on stderr naming the file and the problem, exit status 2, no
traceback, nothing written, input bytes unchanged. One test per case, through the real CLI."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from harness.cli import main
from harness.core.errors import InputError
from harness.io.ply import write_ply
from harness.io.scenes import write_scene
from harness.io.splat import SPLAT_RECORD, write_splat
from tests.scene_factory import random_scene


def snapshot(folder) -> dict:
    return {p.name: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def assert_rejected(capsys, tmp_path, target, *phrases, extra_args=()):
    """Run `harness info target`; check status, the single stderr line and that nothing changed."""
    before = snapshot(tmp_path)
    rc = main(["info", str(target), *extra_args])
    out, err = capsys.readouterr()
    assert rc == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"harness: {target}: "), lines[0]
    for phrase in phrases:
        assert phrase in lines[0], (phrase, lines[0])
    assert "Traceback" not in err
    assert snapshot(tmp_path) == before  # input bytes unchanged, nothing written
    return lines[0]


@pytest.fixture
def good_ply(tmp_path):
    path = tmp_path / "good.ply"
    write_ply(random_scene(50, 1, seed=1), path)
    return path


def test_truncated_ply(capsys, tmp_path, good_ply):
    good_ply.write_bytes(good_ply.read_bytes()[:-10])
    assert_rejected(capsys, tmp_path, good_ply, "truncated", "inside vertex 50 of 50")


def test_header_count_larger_than_data(capsys, tmp_path, good_ply):
    good_ply.write_bytes(good_ply.read_bytes().replace(b"element vertex 50\n", b"element vertex 80\n", 1))
    assert_rejected(capsys, tmp_path, good_ply, "header declares 80 vertices", "only 50")


def test_truncated_header(capsys, tmp_path, good_ply):
    good_ply.write_bytes(good_ply.read_bytes()[:60])
    assert_rejected(capsys, tmp_path, good_ply, "no 'end_header'")


def test_truncated_splat(capsys, tmp_path):
    path = tmp_path / "cut.splat"
    write_splat(random_scene(5, seed=2), path)
    path.write_bytes(path.read_bytes()[:-9])
    assert_rejected(capsys, tmp_path, path, "truncated", "4 complete, 23 bytes left over")


def test_nan_values(capsys, tmp_path):
    scene = random_scene(20, 2, seed=3)
    scene.means[7, 1] = np.nan
    scene.sh_rest[12, 4, 2] = np.nan
    write_ply(scene, tmp_path / "nan.ply")
    assert_rejected(capsys, tmp_path, tmp_path / "nan.ply", "2 of 20 splats have NaN/inf values",
                    "row 7, means", "--drop-nonfinite")


def test_inf_values(capsys, tmp_path):
    scene = random_scene(20, 0, seed=4)
    scene.scales_log[3, 2] = np.inf
    write_ply(scene, tmp_path / "inf.ply")
    assert_rejected(capsys, tmp_path, tmp_path / "inf.ply", "1 of 20 splats have NaN/inf", "row 3, scales_log")


def test_zero_linear_scale_in_splat_is_reported_as_inf(capsys, tmp_path):
    rec = np.zeros(3, SPLAT_RECORD)
    rec["scale"], rec["rot"] = 0.01, (255, 128, 128, 128)
    rec["scale"][1, 0] = 0.0  # log(0) = -inf
    (tmp_path / "z.splat").write_bytes(rec.tobytes())
    assert_rejected(capsys, tmp_path, tmp_path / "z.splat", "1 of 3 splats have NaN/inf", "row 1, scales_log")


def test_drop_nonfinite_drops_and_reports_the_count(capsys, tmp_path):
    scene = random_scene(20, 1, seed=5)
    scene.opacity_logit[[2, 9]] = [np.nan, -np.inf]
    path = tmp_path / "drop.ply"
    write_ply(scene, path)
    before = snapshot(tmp_path)
    assert main(["info", str(path), "--json", "--drop-nonfinite"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["splats"] == 18 and json.loads(out)["dropped_nonfinite"] == 2
    assert err.strip() == f"harness: {path}: dropped 2 splats with NaN/inf values"
    assert snapshot(tmp_path) == before


def test_missing_required_properties(capsys, tmp_path):
    table = np.zeros(4, dtype=[(n, "f4") for n in ("x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2",
                                                   "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2")])
    PlyData([PlyElement.describe(table, "vertex")]).write(str(tmp_path / "m.ply"))
    assert_rejected(capsys, tmp_path, tmp_path / "m.ply", "missing required properties opacity, rot_3")


def test_wrong_sh_coefficient_count(capsys, tmp_path, good_ply):
    data = good_ply.read_bytes()
    good_ply.write_bytes(data.replace(b"property float f_rest_8\n", b"property float f_rest_9\n", 1))
    assert_rejected(capsys, tmp_path, good_ply, "not numbered 0..8", "missing f_rest_8")


def test_zero_norm_quaternion_ply(capsys, tmp_path):
    scene = random_scene(10, 0, seed=6)
    scene.quats[4] = 0.0
    write_ply(scene, tmp_path / "q.ply")
    assert_rejected(capsys, tmp_path, tmp_path / "q.ply", "1 splats have a zero-norm rotation quaternion",
                    "row 4")


def test_zero_norm_quaternion_splat(capsys, tmp_path):
    rec = np.zeros(6, SPLAT_RECORD)
    rec["scale"], rec["rot"] = 0.01, (255, 128, 128, 128)
    rec["rot"][[1, 5]] = 128
    (tmp_path / "q.splat").write_bytes(rec.tobytes())
    assert_rejected(capsys, tmp_path, tmp_path / "q.splat", "2 splats have a zero-norm", "row 1")


def test_unknown_extension(capsys, tmp_path):
    (tmp_path / "scene.xyz").write_bytes(b"1 2 3\n")
    assert_rejected(capsys, tmp_path, tmp_path / "scene.xyz", "unsupported format: text that is not a PLY header")


def test_unreadable_path(capsys, tmp_path):
    assert_rejected(capsys, tmp_path, tmp_path / "missing.ply", "no such file")


def test_folder_that_is_not_a_scene(capsys, tmp_path):
    (tmp_path / "empty").mkdir()
    assert_rejected(capsys, tmp_path, tmp_path / "empty", "folder without lod-meta.json or meta.json")


def test_not_a_ply_file(capsys, tmp_path):
    (tmp_path / "fake.ply").write_bytes(b"\x89PNG\r\n\x1a\n....")
    assert_rejected(capsys, tmp_path, tmp_path / "fake.ply", "unsupported format: a PNG image")


def test_unknown_lod_level_for_single_level_format(capsys, tmp_path, good_ply):
    assert_rejected(capsys, tmp_path, good_ply, "has no LOD levels", extra_args=["--lod", "2"])


def test_writer_rejects_unknown_extension_and_writes_nothing(tmp_path):
    with pytest.raises(InputError, match="cannot write .obj"):
        write_scene(random_scene(3), tmp_path / "out.obj")
    with pytest.raises(InputError, match="output folder does not exist"):
        write_scene(random_scene(3), tmp_path / "nope" / "out.ply")
    assert list(tmp_path.iterdir()) == []


def test_console_script_prints_one_line_without_traceback(tmp_path):
    (tmp_path / "bad.ply").write_bytes(b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nend_header\n1\n")
    proc = subprocess.run([sys.executable, "-m", "harness", "info", str(tmp_path / "bad.ply")],
                          check=False, capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.strip() == (f"harness: {tmp_path / 'bad.ply'}: header declares 2 vertices but the file "
                                   "is too short to hold them (truncated file or wrong count)")
