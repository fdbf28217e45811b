"""Format detection by content: every supported kind is named by `harness info` whatever the file is
called; everything else is one line "unsupported format: <what it looks like>", exit 2; mutated
fixtures (truncated, flipped bytes) load or fail with that one clean line, never a traceback."""

from __future__ import annotations

import io
import json
import struct
import zipfile

import numpy as np
import pytest
import zstandard
from PIL import Image

from harness.io.detect import detect
from harness.io.splat import write_splat
from tests.formats_support import FIXTURES, assert_clean_error, info_line, source

NAMES = {
    "grape_1k.ply": ("ply", "ply (INRIA 3DGS, binary little endian)"),
    "grape_1k.st3.compressed.ply": ("compressed-ply", "compressed-ply (PlayCanvas, 4 chunks, SH degree 3)"),
    "grape_1k.gf.v2.spz": ("spz", "spz v2 (gzip, SH degree 3)"),
    "grape_1k.st3.v4.spz": ("spz", "spz v4 (zstd, 6 streams, SH degree 3)"),
    "grape_1k.gs3d.l1.ksplat": ("ksplat", "ksplat level 1 (v0.1, 1 section, SH degree 2)"),
    "grape_1k_sh0.gf.ksplat": ("ksplat", "ksplat level 0 (v0.1, 1 section, SH degree 0)"),
}


@pytest.mark.parametrize("name", sorted(NAMES))
def test_formats_are_named_by_content_whatever_the_file_is_called(capsys, tmp_path, name):
    kind, shown = NAMES[name]
    for called in (name, "scene.bin"):
        path = tmp_path / called
        path.write_bytes((FIXTURES / name).read_bytes())
        assert detect(path).kind == kind
        rc, out, err = info_line(capsys, path, "--json")
        assert rc == 0 and err == "", err
        info = json.loads(out)
        assert (info["format"], info["format_name"]) == (kind, shown)


def test_text_output_shows_the_format_name(capsys, tmp_path):
    write_splat(source(), tmp_path / "s.splat")
    rc, out, _ = info_line(capsys, tmp_path / "s.splat")
    assert rc == 0 and "format      splat (antimatter15, 32-byte records)\n" in out
    rc, out, _ = info_line(capsys, FIXTURES / "grape_1k.gs3d.l0.ksplat")
    assert rc == 0 and "format      ksplat level 0 (v0.1, 1 section, SH degree 2)\n" in out


def _glb(doc: dict) -> bytes:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    return struct.pack("<4sII", b"glTF", 2, 20 + len(text)) + struct.pack("<I4s", len(text), b"JSON") + text


def _image(fmt: str) -> bytes:
    buf = io.BytesIO()
    Image.new("RGB", (4, 4), (200, 30, 30)).save(buf, fmt)
    return buf.getvalue()


def _zip(names) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name in names:
            z.writestr(name, "{}")
    return buf.getvalue()


UNSUPPORTED = {
    "splats.glb": (_glb({"asset": {"version": "2.0"}, "extensionsUsed": ["KHR_gaussian_splatting"]}),
                   "unsupported format: a glTF binary (.glb) with KHR_gaussian_splatting splats, which the "
                   "harness does not read; export the scene as .ply, .compressed.ply, .spz or .splat instead"),
    "mesh.glb": (_glb({"asset": {"version": "2.0"}, "meshes": []}),
                 "unsupported format: a glTF binary (.glb) without gaussian splats (a mesh or scene)"),
    "image.ply": (_image("PNG"), "unsupported format: a PNG image"),
    "photo.splat.jpg": (_image("JPEG"), "unsupported format: a JPEG image"),
    "texture.webp": (_image("WEBP"), "unsupported format: a WebP image"),
    "empty.spz": (b"", "unsupported format: empty file"),
    "notes.txt": (b"1 2 3\nhello\n", "unsupported format: text that is not a PLY header (starts '1 2 3')"),
    "scene.json": (b'{"means": [1, 2]}', "unsupported format: JSON text (not a SOG meta.json"),
    "archive.zip": (_zip(["a.txt"]), "unsupported format: a zip archive without meta.json"),
    "frame.zst": (zstandard.ZstdCompressor().compress(b"x" * 100), "unsupported format: zstd-compressed data"),
    "doc.pdf": (b"%PDF-1.7\n" + bytes(100), "unsupported format: a PDF document"),
    "noise.bin": (bytes(np.random.default_rng(7).integers(0, 256, 5000, dtype=np.uint8)),
                  "unsupported format: unrecognised binary data (first bytes "),
}


@pytest.mark.parametrize("name", sorted(UNSUPPORTED))
def test_unsupported_formats_get_one_clean_line(capsys, tmp_path, name):
    data, message = UNSUPPORTED[name]
    (tmp_path / name).write_bytes(data)
    line = assert_clean_error(capsys, tmp_path / name, message)
    if name == "noise.bin":
        assert data[:8].hex(" ") in line and "5,000 bytes" in line


def test_a_zip_with_meta_json_is_taken_for_a_sog_bundle(capsys, tmp_path):
    (tmp_path / "bundle.zip").write_bytes(_zip(["meta.json"]))
    assert detect(tmp_path / "bundle.zip").kind == "sog"


# ---------------------------------------------------------------------- mutated fixtures
FUZZED = sorted(p.name for p in FIXTURES.iterdir()
                if p.suffix in (".spz", ".ksplat") or p.name.endswith(".compressed.ply"))


@pytest.mark.parametrize("name", FUZZED)
def test_mutated_fixtures_load_or_fail_cleanly(capsys, tmp_path, name):
    data = (FIXTURES / name).read_bytes()
    rng = np.random.default_rng(sum(name.encode()))
    path = tmp_path / name
    for case in range(12):
        b = bytearray(data)
        if case % 3 == 0:
            b = b[: int(rng.integers(0, len(b)))]
        else:
            span = (0, min(len(b), 5200)) if case % 3 == 1 else (0, len(b))  # headers, or anywhere
            for pos in rng.integers(*span, int(rng.integers(1, 8))):
                b[pos] = int(rng.integers(0, 256))
        path.write_bytes(bytes(b))
        rc, out, err = info_line(capsys, path)
        lines = err.strip().splitlines()
        assert (rc == 0 and err == "") or (rc == 2 and len(lines) == 1 and lines[0].startswith("harness: ")), \
            (name, case, rc, err[-2000:])
