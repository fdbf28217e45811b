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


@pytest.mark.parametrize("case", ["size", "nan", "unreadable", "missing", "device"])
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
    else:
        argv, expect = (a, b, "--device", "warp-drive"), "--device"
    status, out, err = _run(capsys, *argv)
    assert status == 2 and out == ""
    assert err.startswith("harness: ") and expect in err and err.count("\n") == 1
