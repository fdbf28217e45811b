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


# ----------------------------------------------------------------------------- issue 24: bounded reads everywhere
def _png_header_only(path, w, h):
    """A PNG whose IHDR claims w x h pixels and whose data is a few bytes (a decompression bomb)."""
    from tests.stress.cases import _png

    return _png(path, w, h, 0, 8, rows=b"")  # no rows: the header lies


def test_transforms_json_frame_image_bomb_is_one_line(tmp_path, capsys):
    import zlib

    from harness.cli import main

    write_ply(random_scene(30, 0, seed=1), tmp_path / "s.ply")
    raw = zlib.compress(b"\0" * 1000)
    import struct

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    (tmp_path / "a.png").write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", 20000, 20000, 8, 0, 0, 0, 0))
        + chunk(b"IDAT", raw)
        + chunk(b"IEND", b"")
    )
    (tmp_path / "transforms.json").write_text(json.dumps({"camera_angle_x": 0.8, "frames": [
        {"file_path": "a.png", "transform_matrix": np.eye(4).tolist()}]}))
    rc = main(["render", str(tmp_path / "s.ply"), "--cameras", str(tmp_path / "transforms.json"),
               "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "larger than the maximum (8192 per side)" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("kind", ["fifo", "bomb", "truncated"])
def test_report_reads_run_images_through_the_bounded_reader(tmp_path, kind):
    import os
    import time

    from harness.io.safe import open_image
    from harness.report.pageimages import scene_images

    d = tmp_path / "images" / "s"
    d.mkdir(parents=True)
    from PIL import Image

    Image.new("RGB", (8, 6), (10, 20, 30)).save(d / "input.png")
    bad = d / "opacity__default__r0.30.png"
    if kind == "fifo":
        os.mkfifo(bad)
    elif kind == "bomb":
        import struct
        import zlib

        ihdr = struct.pack(">IIBBBBB", 20000, 20000, 8, 2, 0, 0, 0)
        bad.write_bytes(b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + b"IHDR" + ihdr
                        + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr) & 0xFFFFFFFF))
    else:
        good = (d / "input.png").read_bytes()
        bad.write_bytes(good[: len(good) // 2])
    t0 = time.perf_counter()
    with pytest.raises(InputError) as err:
        scene_images(tmp_path / "images", [("s", "s")], {})
    assert str(err.value).startswith(str(bad)) and time.perf_counter() - t0 < 2
    with pytest.raises(InputError):
        open_image(bad)


def test_tex_and_markdown_tables_escape_what_they_embed():
    import pandas as pd

    from harness.report.formats import tex_escape, to_latex, to_markdown

    evil = r"\input{/etc/passwd} $x$ 50% a_b & #1 ^~ <b>"
    disp = pd.DataFrame({"PSNR ↑": ["**31.2**", evil]}, index=pd.Index([evil, "luigi"], name="scene"))
    tex = to_latex(disp, "title " + evil, notes=[evil], label="tab:" + evil)
    assert r"\input{" not in tex and "$x$" not in tex and r"\textbackslash{}input\{/etc/passwd\}" in tex
    assert r"\textbf{31.2}" in tex and r"$\uparrow$" in tex and r"50\%" in tex
    assert tex_escape(r"\\") == r"\textbackslash{}\textbackslash{}"  # one pass: an escape is not escaped again
    md = to_markdown(disp, "t")
    assert "<b>" not in md.replace(r"\<b>", "") and r"\<b>" in md and "**31.2**" in md
    assert "| 0 | x\\|y z |" in to_markdown(pd.DataFrame({"a": ["x|y\nz"]}), "t")  # one row, one cell
