"""`harness compare A B [--json]`: output format and clean errors (exit status 2, one line)."""

import json

import numpy as np
import pytest
from PIL import Image
from skimage import data

from harness.cli import main
from harness.metrics import lpips_weights as lw


@pytest.fixture
def images(tmp_path):
    a = data.astronaut()[:40, :56]
    Image.fromarray(a).save(tmp_path / "a.png")
    b = np.clip(a.astype(np.float32) / 255 + 0.05, 0, 1)
    np.save(tmp_path / "b.npy", b)
    return tmp_path / "a.png", tmp_path / "b.npy"


def _hand_png(path, w: int, h: int):
    """An RGB PNG whose header says ``w`` x ``h``, with one tiny IDAT (no pixel data to speak of)."""
    import struct
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(b"\0")) + chunk(b"IEND", b""))


def test_memory_budget_is_stated_and_can_be_raised(tmp_path, monkeypatch):
    from harness.api.images import check_memory
    from harness.core.errors import InputError

    _hand_png(tmp_path / "c.png", 4096, 4096)
    check_memory(tmp_path / "c.png", ("psnr",))  # 16.8 Mpx by PSNR: ~2 GB, within 4 GiB
    with pytest.raises(InputError, match="to compare by lpips .*at most 2,863,311 pixels"):
        check_memory(tmp_path / "c.png", ("psnr", "lpips"))
    monkeypatch.setenv("HARNESS_MAX_COMPARE_BYTES", str(64 << 30))
    check_memory(tmp_path / "c.png", ("lpips",))


def test_a_huge_header_warns_nothing_before_its_error(tmp_path):
    """Pillow's DecompressionBombWarning (10000x10000 is above its own limit) is not printed before
    the one-line refusal: a transforms.json frame, whose size is read from the image header by Pillow."""
    import subprocess
    import sys

    from harness.io.ply import write_ply
    from tests.scene_factory import random_scene

    _hand_png(tmp_path / "h.png", 10000, 10000)
    write_ply(random_scene(20), tmp_path / "s.ply")
    (tmp_path / "t.json").write_text(json.dumps({"camera_angle_x": 0.8, "frames": [
        {"file_path": "h.png", "transform_matrix": np.eye(4).tolist()}]}))
    proc = subprocess.run([sys.executable, "-W", "default", "-m", "harness", "render", str(tmp_path / "s.ply"),
                           "--cameras", str(tmp_path / "t.json"), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "10000x10000" in proc.stderr, proc.stderr


def _run(capsys, *argv):
    status = main(["compare", *map(str, argv)])
    out, err = capsys.readouterr()
    return status, out, err


@pytest.mark.weights
def test_json_output(images, capsys):
    if not lw.weights_available():
        pytest.skip("LPIPS-VGG weights not converted here: run harness fetch --weights")
    a, b = images
    status, out, _ = _run(capsys, a, b, "--json")
    assert status == 0
    obj = json.loads(out)
    assert {"psnr", "ssim", "lpips", "psnr_inf"} <= set(obj) and obj["psnr_inf"] is False
    expected = -10 * np.log10(np.mean((np.clip(np.asarray(Image.open(a)) / 255 + 0.05, 0, 1)
                                       - np.asarray(Image.open(a)) / 255) ** 2))
    assert obj["psnr"] == pytest.approx(expected, abs=1e-3)
    assert 0 < obj["ssim"] < 1 and obj["lpips"] > 0
    status, out, _ = _run(capsys, a, a, "--json")
    obj = json.loads(out)
    assert obj["psnr"] is None and obj["psnr_inf"] is True and obj["ssim"] == 1.0 and obj["lpips"] == 0.0
    status, out, _ = _run(capsys, a, b)
    assert status == 0 and out.split("\n")[0].startswith("psnr")


@pytest.mark.parametrize("case", ["size", "nan", "unreadable", "missing", "device", "empty", "too large"])
def test_errors_exit_2_with_one_line(images, tmp_path, capsys, case):
    a, b = images
    if case == "size":
        np.save(tmp_path / "c.npy", np.zeros((40, 55, 3), np.float32))
        argv, expect = (a, tmp_path / "c.npy"), "sizes differ"
    elif case == "nan":
        bad = np.zeros((40, 56, 3), np.float32)
        bad[5, 5, 2] = np.nan
        np.save(tmp_path / "c.npy", bad)
        argv, expect = (a, tmp_path / "c.npy"), "NaN"
    elif case == "unreadable":
        (tmp_path / "c.png").write_bytes(b"\x89PNG\r\n\x1a\ngarbage")
        argv, expect = (tmp_path / "c.png", b), "not a readable PNG"
    elif case == "missing":
        argv, expect = (a, tmp_path / "nope.png"), "no such file"
    elif case == "empty":  # Pillow cannot identify a 0x0 PNG: the file and the problem are named, no BytesIO
        _hand_png(tmp_path / "c.png", 0, 0)
        argv, expect = (tmp_path / "c.png", tmp_path / "c.png"), "c.png: image is empty: its PNG header says 0x0"
    elif case == "too large":  # refused from the header, nothing decoded: two 8192² images need ~8 GB for PSNR
        _hand_png(tmp_path / "c.png", 8192, 8192)
        argv, expect = (tmp_path / "c.png", tmp_path / "c.png", "--metrics", "psnr"), "more than compare's"
    else:
        argv, expect = (a, b, "--device", "warp-drive"), "--device"
    status, out, err = _run(capsys, *argv)
    assert status == 2 and out == ""
    assert err.startswith("harness: ") and expect in err and err.count("\n") == 1
