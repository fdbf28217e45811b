"""Niantic .spz: files written by five independent tools (v2, v3, v4) decode to their source within
the format's quantisation; axes; extension records; truncated, inconsistent and bomb files.

Bounds (harness/io/spz.py): position ``≤ ½/4096``; log-scale ``≤ 1/32`` against the source clipped
to [−10, 5.9375]; linear alpha ``≤ ½/255``; f_dc ``≤ ½/38.25`` (clipped to ±127.5/38.25); unit
quaternions ``≤ 2e-3`` (v3+, smallest three) or, for v2, x, y, z ``≤ ½/127.5`` with w ≥ 0 (w is
derived, so the whole quaternion is not bounded tightly); f_rest against the source clipped to
[−1, 127/128]: ``≤ 4.5/128`` (band 1) and ``≤ 8.5/128`` (bands 2-3) for Niantic's bucketed
quantiser, ``≤ ½/128`` for gsply's.
"""

from __future__ import annotations

import gzip
import struct
import tracemalloc
import zlib

import numpy as np
import pytest
import zstandard

from harness.io.spz import read_spz
from tests.formats_support import (
    FIXTURES,
    alpha,
    assert_clean_error,
    assert_within,
    info_line,
    match,
    quat_error,
    source_for,
    unit_quats,
)

WRITERS = {  # fixture -> (writer, axes on disk, SH quantiser)
    "grape_1k.st3.v3.spz": ("splat-transform 3.7.0", "PLY", "niantic"),
    "grape_1k.st3.v4.spz": ("splat-transform 3.7.0", "PLY", "niantic"),
    "grape_1k_sh0.st3.v4.spz": ("splat-transform 3.7.0", "PLY", "niantic"),
    "grape_1k.st2.v3.spz": ("splat-transform 2.7.1", "RUB", "niantic"),
    "grape_1k.st2.v4.spz": ("splat-transform 2.7.1", "RUB", "niantic"),
    "grape_1k.gsply.v3.spz": ("gsply 0.4.6", "PLY", "exact"),
    "grape_1k.gsply.v4.spz": ("gsply 0.4.6", "PLY", "exact"),
    "grape_1k.gf.v2.spz": ("gaussforge 0.6.0", "PLY", "niantic"),
    "grape_1k.gf.v3.spz": ("gaussforge 0.6.0", "PLY", "niantic"),
    "grape_1k.gf.v4.spz": ("gaussforge 0.6.0", "PLY", "niantic"),
    "grape_1k_sh0.gf.v3.spz": ("gaussforge 0.6.0", "PLY", "niantic"),
    "grape_1k.spzjs.v2.spz": ("spz-js 1.2.5", "PLY", "niantic"),
}
_EPS = 1e-6


def _v2_xyz_error(decoded: np.ndarray, src: np.ndarray) -> np.ndarray:
    """x, y, z error of v2 quaternions: the writer negates q so that w ≥ 0 (ambiguous when w ≈ 0)."""
    src = src * np.where(src[:, :1] < 0, -1.0, 1.0)
    err = np.abs(decoded[:, 1:] - src[:, 1:]).max(1)
    flipped = np.abs(decoded[:, 1:] + src[:, 1:]).max(1)
    return np.where(np.abs(src[:, 0]) < 1e-4, np.minimum(err, flipped), err)


def check_against_source(decoded, src, version: int, sh_quantiser: str) -> dict:
    errors: dict = {}
    assert_within("position", np.abs(decoded.means - src.means), 0.5 / 4096 + _EPS, errors)
    assert_within("log-scale", np.abs(decoded.scales_log - np.clip(src.scales_log, -10, 5.9375)), 1 / 32 + _EPS, errors)
    errors["log-scale (unclipped)"] = float(np.abs(decoded.scales_log - src.scales_log).max())
    q, q_src = unit_quats(decoded), unit_quats(src)
    if version >= 3:
        assert_within("rotation", quat_error(q, q_src), 2e-3, errors)
    else:  # the stored x, y, z as decoded (w derived), before any renormalisation
        assert_within("rotation xyz (v2)", _v2_xyz_error(decoded.quats.astype(np.float64), q_src),
                      0.5 / 127.5 + _EPS, errors)
        errors["rotation"] = float(quat_error(q, q_src).max())
    assert_within("alpha", np.abs(alpha(decoded) - alpha(src)), 0.5 / 255 + _EPS, errors)
    limit = 127.5 / 38.25
    assert_within("f_dc", np.abs(decoded.sh_dc - np.clip(src.sh_dc, -limit, limit)), 0.5 / 38.25 + _EPS, errors)
    k = decoded.sh_rest.shape[1]
    assert src.sh_rest.shape[1] == k
    if k:
        if sh_quantiser == "exact":
            bound = np.full((k, 1), 0.5 / 128)
        else:
            bound = np.where(np.arange(k) < 3, 4.5 / 128, 8.5 / 128)[:, None]
        diff = np.abs(decoded.sh_rest - np.clip(src.sh_rest, -1, 127 / 128))
        assert_within("f_rest", diff, bound + _EPS, errors)
    return errors


def measure_fixture(name: str) -> dict:
    _, axes, quantiser = WRITERS[name]
    decoded = read_spz(FIXTURES / name, axes=axes)
    src = source_for(name)
    assert len(decoded) == len(src)
    version = int(name.split(".v")[1][0])
    return {"count": len(decoded), **check_against_source(decoded, src.subset(match(decoded, src)), version, quantiser)}


@pytest.mark.parametrize("name", sorted(WRITERS))
def test_independent_writers_decode_within_quantisation(name):
    assert measure_fixture(name)["count"] == 1000


@pytest.mark.parametrize("name, shown", [("grape_1k.gf.v2.spz", "spz v2 (gzip, SH degree 3)"),
                                         ("grape_1k.st3.v3.spz", "spz v3 (gzip, SH degree 3)"),
                                         ("grape_1k_sh0.st3.v4.spz", "spz v4 (zstd, 5 streams, SH degree 0)")])
def test_harness_info_names_the_version(capsys, tmp_path, name, shown):
    renamed = tmp_path / "scene.bin"  # detected by content, not by name
    renamed.write_bytes((FIXTURES / name).read_bytes())
    rc, out, _ = info_line(capsys, renamed)
    assert rc == 0 and f"format      {shown}\n" in out


def test_axes_default_to_ply_and_rub_files_need_the_option():
    rub = FIXTURES / "grape_1k.st2.v3.spz"
    as_stored, converted = read_spz(rub), read_spz(rub, axes="RUB")
    np.testing.assert_array_equal(as_stored.means * np.array([1, -1, -1], np.float32), converted.means)
    np.testing.assert_array_equal(as_stored.quats * np.array([1, 1, -1, -1], np.float32), converted.quats)
    signs = np.array([-1, -1, 1, -1, 1, 1, -1, 1, -1, 1, -1, -1, 1, -1, 1], np.float32)[:, None]  # flipSh, y=z=-1
    np.testing.assert_array_equal(as_stored.sh_rest * signs, converted.sh_rest)
    np.testing.assert_array_equal(read_spz(FIXTURES / "grape_1k.st3.v3.spz", axes="ply").means,
                                  read_spz(FIXTURES / "grape_1k.st3.v3.spz").means)


# ---------------------------------------------------------------------- extension records
def _record(kind: int, payload: bytes) -> bytes:
    return struct.pack("<II", kind, len(payload)) + payload


def _with_v4_extensions(data: bytes, extensions: bytes) -> bytes:
    """A v4 file with ``extensions`` inserted before its table of contents (flag 0x2 set)."""
    head = bytearray(data[:32])
    toc = struct.unpack_from("<I", head, 16)[0]
    head[14] |= 2
    struct.pack_into("<I", head, 16, toc + len(extensions))
    return bytes(head) + data[32:toc] + extensions + data[toc:]


def _legacy_parts(data: bytes) -> tuple[bytearray, bytes]:
    raw = gzip.decompress(data)
    return bytearray(raw[:16]), raw[16:]


@pytest.mark.parametrize("value", [4, 0])  # RUB, and UNSPECIFIED which the record defines as RUB
def test_v4_coordinate_system_record_is_honoured(tmp_path, value):
    rub = (FIXTURES / "grape_1k.st2.v4.spz").read_bytes()
    ext = _record(0x12340001, b"skip me") + _record(0xADBE0003, struct.pack("<I", value))
    path = tmp_path / "stated.spz"
    path.write_bytes(_with_v4_extensions(rub, ext))
    decoded = read_spz(path)
    np.testing.assert_array_equal(decoded.means, read_spz(FIXTURES / "grape_1k.st2.v4.spz", axes="RUB").means)
    check_against_source(decoded, source_for("grape_1k").subset(match(decoded, source_for("grape_1k"))), 4, "niantic")


def test_legacy_trailing_coordinate_system_record_is_honoured(tmp_path):
    head, body = _legacy_parts((FIXTURES / "grape_1k.st2.v3.spz").read_bytes())
    head[14] |= 2
    path = tmp_path / "stated.spz"
    path.write_bytes(gzip.compress(bytes(head) + body + _record(0xADBE0003, struct.pack("<I", 4))))
    np.testing.assert_array_equal(read_spz(path).means, read_spz(FIXTURES / "grape_1k.st2.v3.spz", axes="RUB").means)


def test_ply_record_and_axis_permuting_record(capsys, tmp_path):
    ply = (FIXTURES / "grape_1k.st3.v4.spz").read_bytes()
    (tmp_path / "rdf.spz").write_bytes(_with_v4_extensions(ply, _record(0xADBE0003, struct.pack("<I", 6))))
    as_ply = read_spz(FIXTURES / "grape_1k.st3.v4.spz")
    np.testing.assert_array_equal(read_spz(tmp_path / "rdf.spz").means, as_ply.means)
    (tmp_path / "rbd.spz").write_bytes(_with_v4_extensions(ply, _record(0xADBE0003, struct.pack("<I", 10))))
    assert_clean_error(capsys, tmp_path / "rbd.spz", "coordinate system 10 permutes axes")


# ---------------------------------------------------------------------- bad files
def _legacy(n: int, payload: bytes, version=3, sh=0, flags=0, level=6) -> bytes:
    return gzip.compress(b"NGSP" + struct.pack("<IIBBBB", version, n, sh, 12, flags, 0) + payload, level)


def _v4(n: int, streams: list[bytes], sh=0, sizes=None) -> bytes:
    frames = [zstandard.ZstdCompressor().compress(s) for s in streams]
    sizes = sizes or [len(s) for s in streams]
    head = b"NGSP" + struct.pack("<IIBBBBI12x", 4, n, sh, 12, 0, len(frames), 32)
    toc = b"".join(struct.pack("<QQ", len(f), u) for f, u in zip(frames, sizes))
    return head + toc + b"".join(frames)


def _v3_streams(n: int) -> list[bytes]:
    return [bytes(9 * n), bytes(n), bytes(3 * n), bytes(3 * n), bytes(4 * n)]


@pytest.mark.parametrize("cut", [0.5, 0.98])
def test_truncated_gzip_file(capsys, tmp_path, cut):
    data = (FIXTURES / "grape_1k.st3.v3.spz").read_bytes()
    (tmp_path / "cut.spz").write_bytes(data[: int(len(data) * cut)])
    assert_clean_error(capsys, tmp_path / "cut.spz", "truncated spz: 1,000 points need 65,016 decompressed bytes")


def test_truncated_zstd_file(capsys, tmp_path):
    data = (FIXTURES / "grape_1k.st3.v4.spz").read_bytes()
    (tmp_path / "cut.spz").write_bytes(data[:-1000])
    assert_clean_error(capsys, tmp_path / "cut.spz", "compressed streams add up to", "truncated or corrupt")
    (tmp_path / "toc.spz").write_bytes(_v4(10, _v3_streams(10))[:40])
    assert_clean_error(capsys, tmp_path / "toc.spz", "table of contents at byte 32 lies outside")


def test_count_larger_than_the_data(capsys, tmp_path):
    head, body = _legacy_parts((FIXTURES / "grape_1k.st3.v3.spz").read_bytes())
    struct.pack_into("<I", head, 8, 1500)
    (tmp_path / "more.spz").write_bytes(gzip.compress(bytes(head) + body))
    assert_clean_error(capsys, tmp_path / "more.spz", "1,500 points need")
    (tmp_path / "v4.spz").write_bytes(_v4(20, _v3_streams(10)))
    assert_clean_error(capsys, tmp_path / "v4.spz", "stream sizes do not match the point count")


@pytest.mark.parametrize("data, phrase", [
    (_legacy(4_000_000_000, b""), "spz header declares 4,000,000,000 points, impossible for a"),
    (b"NGSP" + struct.pack("<IIBBBBI12x", 4, 3_000_000_000, 3, 12, 0, 6, 32), "impossible for a 32-byte file"),
    (_legacy(0, b""), "declares 0 points"),
    (_legacy(10, bytes(500), version=7), "unsupported spz version 7 in a gzip stream"),
    (_legacy(10, bytes(500), version=4), "unsupported spz version 4 in a gzip stream"),
    (b"NGSP" + struct.pack("<IIBBBBI12x", 5, 10, 0, 12, 0, 5, 32), "unsupported spz version 5 in an NGSP header"),
    (_legacy(10, bytes(10_000), sh=4), "SH degree 4 is not supported"),
    (_legacy(10, bytes(10_000), sh=9), "SH degree 9 is not valid"),
    (_v4(10, _v3_streams(10)[:4]), "lists 4 streams; 10 points of SH degree 0 need 5"),
    (gzip.compress(b"hello world, not splats" * 10), "unsupported format: a gzip file that is not spz"),
    (b"NGSP\x04\x00", "unsupported format: an spz header too short"),
])
def test_inconsistent_headers(capsys, tmp_path, data, phrase):
    (tmp_path / "bad.spz").write_bytes(data)
    assert_clean_error(capsys, tmp_path / "bad.spz", phrase)


def test_corrupt_compressed_data(capsys, tmp_path):
    data = bytearray((FIXTURES / "grape_1k.st3.v4.spz").read_bytes())
    data[200:260] = bytes(60)
    (tmp_path / "z.spz").write_bytes(bytes(data))
    assert_clean_error(capsys, tmp_path / "z.spz", "corrupt zstd stream")
    data = bytearray((FIXTURES / "grape_1k.st3.v3.spz").read_bytes())
    data[5000:5400] = bytes(range(200)) * 2
    (tmp_path / "g.spz").write_bytes(bytes(data))
    assert_clean_error(capsys, tmp_path / "g.spz", "corrupt gzip data")


def _peak_bytes(fn) -> int:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_gzip_bomb_inflates_only_what_the_header_needs(tmp_path):
    comp = zlib.compressobj(9, wbits=31)
    parts = [comp.compress(b"NGSP" + struct.pack("<IIBBBB", 3, 10, 0, 12, 0, 0))]
    zeros = bytes(1 << 20)
    parts += [comp.compress(zeros) for _ in range(64)]  # 64 MiB of zeros after the 10 splats
    (tmp_path / "bomb.spz").write_bytes(b"".join(parts) + comp.flush())
    assert (tmp_path / "bomb.spz").stat().st_size < 100_000
    scene = []
    assert _peak_bytes(lambda: scene.append(read_spz(tmp_path / "bomb.spz"))) < 8 << 20
    assert len(scene[0]) == 10


def test_zstd_bomb_stops_at_the_table_size(capsys, tmp_path):
    n = 10
    streams = _v3_streams(n)
    streams[0] = bytes(64 << 20)  # the positions frame inflates to 64 MiB, the table says 90 bytes
    data = _v4(n, streams, sizes=[9 * n, n, 3 * n, 3 * n, 4 * n])
    (tmp_path / "bomb.spz").write_bytes(data)
    assert len(data) < 100_000
    peak = _peak_bytes(lambda: assert_clean_error(capsys, tmp_path / "bomb.spz", "decompresses to 91 bytes"))
    assert peak < 8 << 20
