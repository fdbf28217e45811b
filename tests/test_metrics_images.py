"""Reading PNG / .npy images for the metrics, and their clean input errors."""

import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from harness.core.errors import InputError
from harness.metrics.images import as_image, read_image


def _png_16bit_rgb(path, h=2, w=3):
    """A minimal valid 16-bit RGB PNG (Pillow cannot write one)."""
    def chunk(tag, body):
        return struct.pack(">I", len(body)) + tag + body + struct.pack(">I", zlib.crc32(tag + body))
    raw = b"".join(b"\x00" + bytes(w * 6) for _ in range(h))
    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, 2, 0, 0, 0))
           + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))
    path.write_bytes(png)


def test_png_8bit_rgb_rgba_grey(tmp_path):
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (5, 7, 3), dtype=np.uint8)
    Image.fromarray(rgb).save(tmp_path / "rgb.png")
    assert np.array_equal(read_image(tmp_path / "rgb.png"), rgb.astype(np.float32) / 255)
    rgba = np.concatenate([rgb, rng.integers(0, 256, (5, 7, 1), dtype=np.uint8)], axis=2)
    Image.fromarray(rgba).save(tmp_path / "rgba.png")
    assert np.array_equal(read_image(tmp_path / "rgba.png"), rgb.astype(np.float32) / 255)  # alpha dropped
    Image.fromarray(rgb[..., 0]).save(tmp_path / "grey.png")
    grey = read_image(tmp_path / "grey.png")
    assert grey.shape == (5, 7, 3) and np.array_equal(grey[..., 2], rgb[..., 0] / np.float32(255))


def test_png_16bit_grey_and_colour(tmp_path):
    g16 = np.arange(35, dtype=np.uint16).reshape(5, 7) * 1800
    Image.fromarray(g16).save(tmp_path / "g16.png")
    assert np.allclose(read_image(tmp_path / "g16.png")[..., 1], g16 / 65535.0, atol=1e-7)
    _png_16bit_rgb(tmp_path / "c16.png")
    with pytest.raises(InputError, match="16-bit colour"):
        read_image(tmp_path / "c16.png")


def test_npy_float_and_uint8(tmp_path):
    f = np.random.default_rng(1).random((4, 6, 3)).astype(np.float64) * 1.2  # out of range kept as read
    np.save(tmp_path / "f.npy", f)
    assert np.array_equal(read_image(tmp_path / "f.npy"), f.astype(np.float32))
    u = np.full((4, 6, 4), 255, np.uint8)
    np.save(tmp_path / "u.npy", u)
    assert np.array_equal(read_image(tmp_path / "u.npy"), np.ones((4, 6, 3), np.float32))


@pytest.mark.parametrize(
    "case", ["missing", "garbage", "truncated_png", "jpeg", "pickled_npy", "nan", "shape", "dtype"]
)
def test_bad_files_raise_input_error(tmp_path, case):
    p = tmp_path / ("x.npy" if case in ("pickled_npy", "nan", "shape", "dtype") else "x.png")
    if case == "garbage":
        p.write_bytes(b"not an image at all")
    elif case == "truncated_png":
        Image.fromarray(np.zeros((50, 50, 3), np.uint8) + 7).save(p)
        p.write_bytes(p.read_bytes()[:60])
    elif case == "jpeg":
        Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(p, format="JPEG")
    elif case == "pickled_npy":
        np.save(p, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    elif case == "nan":
        a = np.zeros((4, 4, 3), np.float32)
        a[2, 1, 0] = np.nan
        np.save(p, a)
    elif case == "shape":
        np.save(p, np.zeros((4, 4, 3, 2), np.float32))
    elif case == "dtype":
        np.save(p, np.zeros((4, 4, 3), np.complex64))
    with pytest.raises(InputError) as err:
        read_image(p)
    assert str(p) in str(err.value) and "\n" not in str(err.value)


def test_as_image_rejects_empty():
    with pytest.raises(InputError, match="empty"):
        as_image(np.zeros((0, 4, 3), np.float32))
