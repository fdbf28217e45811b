"""mkkellogg .ksplat: files from GaussianSplats3D (levels 0, 1, 2) and gaussforge decode to their
source within the format's quantisation; inconsistent headers and truncated files fail cleanly.

Bounds (harness/io/ksplat.py): level 0 stores float32 (positions, scales, rotations, SH: float
rounding only); levels 1-2 store positions as u16 offsets from a bucket centre (``≤ block/2/32767/2``)
and scales, rotations, level-1 SH as float16 converted by three.js, which truncates (relative error
``< 2⁻¹⁰``, absolute ``2⁻²⁴`` below the normal range; scales below 2⁻²⁴ read back as 2⁻²⁴). Colour
and alpha bytes are floored: ``< 1/255`` (f_dc ``< 1/255/SH_C0`` for colours within [0, 1]). Level-2
SH bytes are floored over the header's [min, max]: ``< (max − min)/255``. GaussianSplats3D keeps SH
degree ≤ 2 and drops splats whose alpha byte is 0.
"""

from __future__ import annotations

import struct

import numpy as np
import pytest

from harness.core.scene import SH_C0
from harness.io.ksplat import read_ksplat
from tests.formats_support import (
    FIXTURES,
    alpha,
    assert_clean_error,
    assert_within,
    colour,
    info_line,
    match,
    quat_error,
    source_for,
    unit_quats,
)

WRITERS = {  # fixture -> (writer, level, drops alpha byte 0)
    "grape_1k.gs3d.l0.ksplat": ("GaussianSplats3D 0.4.7", 0, True),
    "grape_1k.gs3d.l1.ksplat": ("GaussianSplats3D 0.4.7", 1, True),
    "grape_1k.gs3d.l2.ksplat": ("GaussianSplats3D 0.4.7", 2, True),
    "grape_1k_sh0.gs3d.l1.ksplat": ("GaussianSplats3D 0.4.7", 1, True),
    "grape_1k_sh0.gf.ksplat": ("gaussforge 0.6.0", 0, False),
}
_EPS = 1e-6


def check_against_source(decoded, src, level: int, sh_range=None) -> dict:
    errors: dict = {}
    position_bound = 1e-7 if level == 0 else 5.0 / 2 / 32767 / 2 + _EPS
    assert_within("position", np.abs(decoded.means - src.means), position_bound, errors)
    lin, lin_src = np.exp(decoded.scales_log.astype(np.float64)), np.exp(src.scales_log.astype(np.float64))
    if level == 0:
        assert_within("log-scale", np.abs(decoded.scales_log - src.scales_log), _EPS, errors)
    else:
        bound = np.maximum(lin_src * 2.0**-10, 2.0**-24) * (1 + 1e-5)
        assert_within("scale (linear)", np.abs(lin - lin_src), bound, errors)
        normal = src.scales_log >= np.log(2.0**-14)
        errors["log-scale (half-float normal range)"] = float(np.abs(decoded.scales_log - src.scales_log)[normal].max())
        errors["log-scale (unclipped)"] = float(np.abs(decoded.scales_log - src.scales_log).max())
    assert_within("rotation", quat_error(unit_quats(decoded), unit_quats(src)), _EPS if level == 0 else 1.5e-3, errors)
    assert_within("alpha", np.abs(alpha(decoded) - alpha(src)), 1 / 255 + _EPS, errors)
    diff = np.abs(colour(decoded.sh_dc) - np.clip(colour(src.sh_dc), 0, 1))
    assert_within("f_dc", diff / SH_C0, 1 / 255 / SH_C0 + 1e-5, errors)
    k = decoded.sh_rest.shape[1]
    if k:
        want = src.sh_rest[:, :k].astype(np.float64)
        if level == 0:
            assert_within("f_rest", np.abs(decoded.sh_rest - want), 1e-7, errors)
        elif level == 1:
            bound = np.maximum(np.abs(want) * 2.0**-10, 2.0**-24) + 1e-7
            assert_within("f_rest", np.abs(decoded.sh_rest - want), bound, errors)
        else:
            lo, hi = sh_range
            assert_within("f_rest", np.abs(decoded.sh_rest - np.clip(want, lo, hi)), (hi - lo) / 255 + _EPS, errors)
    return errors


def measure_fixture(name: str) -> dict:
    path = FIXTURES / name
    _, level, drops = WRITERS[name]
    decoded = read_ksplat(path)
    src = source_for(name)
    kept = np.floor(alpha(src) * 255) >= 1
    assert len(decoded) == (int(kept.sum()) if drops else len(src))
    assert decoded.sh_degree == min(src.sh_degree, 2)
    sh_range = struct.unpack_from("<ff", path.read_bytes(), 36)
    return {"count": len(decoded), **check_against_source(decoded, src.subset(match(decoded, src)), level, sh_range)}


@pytest.mark.parametrize("name", sorted(WRITERS))
def test_independent_writers_decode_within_quantisation(name):
    assert measure_fixture(name)["count"] in (909, 1000)


def test_harness_info_names_the_level_and_detects_by_content(capsys, tmp_path):
    renamed = tmp_path / "scene.dat"
    renamed.write_bytes((FIXTURES / "grape_1k.gs3d.l2.ksplat").read_bytes())
    rc, out, _ = info_line(capsys, renamed)
    assert rc == 0 and "format      ksplat level 2 (v0.1, 1 section, SH degree 2)\n" in out and "909" in out


def test_sections_are_concatenated(tmp_path):
    """Two sections (the second a copy of the first) read as twice the splats, in file order."""
    data = (FIXTURES / "grape_1k_sh0.gs3d.l1.ksplat").read_bytes()
    head, section, body = bytearray(data[:4096]), data[4096:5120], data[5120:]
    struct.pack_into("<IIII", head, 4, 2, 2, 2 * 909, 2 * 909)
    (tmp_path / "two.ksplat").write_bytes(bytes(head) + section + section + body + body)
    one, two = read_ksplat(FIXTURES / "grape_1k_sh0.gs3d.l1.ksplat"), read_ksplat(tmp_path / "two.ksplat")
    assert len(two) == 2 * len(one)
    np.testing.assert_array_equal(two.means[909:], one.means)


# ---------------------------------------------------------------------- bad files
def _edit(tmp_path, fixture: str, fmt: str, offset: int, *values, cut: int = 0):
    data = bytearray((FIXTURES / fixture).read_bytes())
    struct.pack_into(fmt, data, offset, *values)
    path = tmp_path / "bad.ksplat"
    path.write_bytes(bytes(data[: len(data) - cut]))
    return path


@pytest.mark.parametrize("fmt, offset, values, cut, phrase", [
    ("<I", 0, (0x0100,), 100, "headers describe 48,804 bytes but the file has 48,704"),
    ("<I", 4096 + 4, (5000,), 0, "headers describe"),            # section capacity beyond the data
    ("<I", 4096, (950,), 0, "more splats than its capacity"),
    ("<I", 16, (1000,), 0, "header counts 1,000 splats, its sections 909"),
    ("<I", 4, (70000,), 0, "header lists 70,000 sections; their headers need"),
    ("<H", 20, (3,), 0, "compression level 3 is not supported"),
    ("<BB", 0, (1, 0), 0, "unsupported format"),                 # not 0.x: not recognised as a ksplat
    ("<H", 4096 + 40, (5,), 0, "SH degree 5; expected 0-3"),
    ("<I", 5120, (10,), 0, "buckets hold fewer splats"),        # the partial bucket lists 10 of 141
    ("<H", 4096 + 20, (8,), 0, "bucket entries must be 12 bytes"),
])
def test_inconsistent_headers(capsys, tmp_path, fmt, offset, values, cut, phrase):
    path = _edit(tmp_path, "grape_1k.gs3d.l2.ksplat", fmt, offset, *values, cut=cut)
    assert_clean_error(capsys, path, phrase)


def test_short_files(capsys, tmp_path):
    (tmp_path / "short.ksplat").write_bytes(bytes([0, 1, 0, 0]) + bytes(100))
    assert_clean_error(capsys, tmp_path / "short.ksplat", "4096-byte header; the file has 104 bytes")


def test_non_finite_level0_values_are_reported(capsys, tmp_path):
    record = 4096 + 1024  # level 0, no buckets: the first record's x
    path = _edit(tmp_path, "grape_1k_sh0.gf.ksplat", "<f", record, float("nan"))
    assert_clean_error(capsys, path, "1 of 1000 splats have NaN/inf values", "row 0, means")
