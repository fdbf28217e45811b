"""PlayCanvas compressed.ply: files written by independent tools decode to their source within the
format's quantisation; our writer round-trips (property test) and splat-transform reads its output.

Bounds (per splat, from the file's own chunk table; see harness/io/compressed_ply.py):
position and log-scale ``≤ (max − min)/(2^bits − 1)/2`` (11/10/11 bits; log-scale against the
source clipped to the chunk range), colour ``≤ range/255/2`` (f_dc = colour/SH_C0), linear alpha
``≤ ½/255``, unit quaternion components ``≤ 2.5e-3`` (three stored to √2/1023/2, the fourth derived),
f_rest ``≤ 1/64`` (``1/32`` at the end codes ±4; source clipped to ±4).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from harness.core.scene import SH_C0, GaussianScene
from harness.io.compressed_ply import encode_compressed_ply, write_compressed_ply
from harness.io.files import atomic_write_chunks
from harness.io.ply import read_binary_elements, read_ply, read_ply_header
from harness.io.scenes import read_scene, write_scene
from tests.formats_support import (
    FIXTURES,
    alpha,
    assert_clean_error,
    assert_within,
    colour,
    info_line,
    match,
    quat_error,
    run_splat_transform,
    source,
    source_for,
    splat_transform,
    unit_quats,
)
from tests.scene_factory import random_scene

WRITERS = {  # fixture -> (writer, drops splats with alpha <= 1/255)
    "grape_1k.st3.compressed.ply": ("splat-transform 3.7.0", False),
    "grape_1k_sh0.st3.compressed.ply": ("splat-transform 3.7.0", False),
    "grape_1k.gsply.compressed.ply": ("gsply 0.4.6", False),
    "grape_1k.spzjs.compressed.ply": ("spz-js 1.2.5", False),
    "grape_1k.gsplat.compressed.ply": ("gsplat 1.5.3", True),
    "grape_1k_sh0.gsplat.compressed.ply": ("gsplat 1.5.3", True),
}
_BITS = np.array([2047.0, 1023.0, 2047.0])
_EPS = 1e-6


def check_against_source(path, decoded: GaussianScene, src: GaussianScene) -> dict:
    """Assert the documented bounds of every attribute of ``decoded`` (file order) against ``src``
    (the same rows); returns the max error of each attribute."""
    chunk = read_binary_elements(path, read_ply_header(path))["chunk"]
    ci = np.arange(len(decoded)) // 256
    table = lambda *names: np.stack([chunk[n].astype(np.float64) for n in names], 1)[ci]  # noqa: E731
    errors: dict = {}
    lo, hi = table("min_x", "min_y", "min_z"), table("max_x", "max_y", "max_z")
    ulps = 2 * np.spacing(np.maximum(np.abs(lo), np.abs(hi)).astype(np.float32))  # float32 bounds and decode
    assert_within("position", np.abs(decoded.means - src.means), (hi - lo) / _BITS / 2 + ulps + _EPS, errors)
    lo = table("min_scale_x", "min_scale_y", "min_scale_z")
    hi = table("max_scale_x", "max_scale_y", "max_scale_z")
    assert_within("log-scale", np.abs(decoded.scales_log - np.clip(src.scales_log, lo, hi)),
                  (hi - lo) / _BITS / 2 + 1e-5, errors)
    errors["log-scale (unclipped)"] = float(np.abs(decoded.scales_log - src.scales_log).max(initial=0))
    assert_within("rotation", quat_error(unit_quats(decoded), unit_quats(src)), 2.5e-3, errors)
    assert_within("alpha", np.abs(alpha(decoded) - alpha(src)), 0.5 / 255 + _EPS, errors)
    lo, hi = table("min_r", "min_g", "min_b"), table("max_r", "max_g", "max_b")
    diff = np.abs(colour(decoded.sh_dc) - np.clip(colour(src.sh_dc), lo, hi))
    assert_within("f_dc", diff / SH_C0, (hi - lo) / 255 / 2 / SH_C0 + 1e-5, errors)
    k = decoded.sh_rest.shape[1]
    assert src.sh_rest.shape[1] == k
    if k:
        rest = decoded.sh_rest.astype(np.float64)
        bound = np.where(np.abs(rest) == 4.0, 1 / 32, 1 / 64) + _EPS
        assert_within("f_rest", np.abs(rest - np.clip(src.sh_rest, -4, 4)), bound, errors)
    return errors


def measure_fixture(name: str) -> dict:
    path = FIXTURES / name
    decoded = read_scene(path).scene
    src = source_for(name)
    drops = WRITERS[name][1]
    assert len(decoded) == (int((alpha(src) > 1 / 255).sum()) if drops else len(src))
    errors = check_against_source(path, decoded, src.subset(match(decoded, src)))
    return {"count": len(decoded), **errors}


@pytest.mark.parametrize("name", sorted(WRITERS))
def test_independent_writers_decode_within_quantisation(name):
    errors = measure_fixture(name)
    assert errors["count"] in (909, 1000)


def test_harness_info_names_the_format(capsys):
    rc, out, _ = info_line(capsys, FIXTURES / "grape_1k.st3.compressed.ply")
    assert rc == 0
    assert "format      compressed-ply (PlayCanvas, 4 chunks, SH degree 3)" in out
    assert "splats      1,000" in out


def test_gsplat_sh0_file_has_an_empty_sh_element():
    header = read_ply_header(FIXTURES / "grape_1k_sh0.gsplat.compressed.ply")
    assert header.element("sh") is not None and header.element("sh").properties == []
    assert read_ply(FIXTURES / "grape_1k_sh0.gsplat.compressed.ply").sh_degree == 0


# ---------------------------------------------------------------------- our writer
def _wide_scene(n: int, degree: int, seed: int, spread: float) -> GaussianScene:
    scene = random_scene(n, degree, seed)
    rng = np.random.default_rng(seed)
    means = scene.means * spread
    scales_log = scene.scales_log + rng.normal(0, 4, size=scene.scales_log.shape)  # some beyond ±20
    opacity = np.where(rng.random(n) < 0.1, rng.choice([-30.0, 30.0], n), scene.opacity_logit)
    sh_rest = scene.sh_rest * 30  # some beyond the ±4 the SH bytes hold
    return GaussianScene.from_arrays(means, scales_log, scene.quats, opacity, scene.sh_dc * 2, sh_rest)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(n=st.integers(1, 700), degree=st.integers(0, 3), seed=st.integers(0, 2**31),
       spread=st.sampled_from([1e-3, 1.0, 50.0]))
def test_write_read_round_trip_within_quantisation(tmp_path, n, degree, seed, spread):
    scene = _wide_scene(n, degree, seed, spread)
    path = tmp_path / "r.compressed.ply"
    order = write_compressed_ply(scene, path)
    assert sorted(order) == list(range(n))
    decoded = read_ply(path)
    assert len(decoded) == n and decoded.sh_degree == degree
    check_against_source(path, decoded, scene.subset(order))


def test_writer_layout_and_morton_order(tmp_path):
    scene = source()
    data, order = encode_compressed_ply(scene, comments=["from grape_1k"])
    header = data[0].decode()
    assert header.startswith("ply\nformat binary_little_endian 1.0\ncomment from grape_1k\nelement chunk 4\n")
    assert "element vertex 1000\n" in header and "element sh 1000\n" in header and "f_rest_44" in header
    shuffled = random_scene(8192, 0, seed=1)  # rows in random spatial order
    _, order = encode_compressed_ply(shuffled)
    extent = lambda m: np.mean([np.ptp(m[i:i + 256], axis=0).sum() for i in range(0, len(m), 256)])  # noqa: E731
    assert extent(shuffled.means[order]) < 0.5 * extent(shuffled.means)  # Morton chunks are compact
    path = write_scene(scene.with_sh_degree(0), tmp_path / "s.compressed.ply")
    assert read_ply_header(path).element("sh") is None


def test_empty_scene_round_trips(tmp_path):
    empty = source().subset(np.zeros(0, int))
    write_compressed_ply(empty, tmp_path / "e.compressed.ply")
    assert len(read_ply(tmp_path / "e.compressed.ply")) == 0


def test_extras_are_dropped(tmp_path):
    scene = random_scene(10, 1, seed=2, extra=True)
    write_compressed_ply(scene, tmp_path / "x.compressed.ply")
    assert read_ply(tmp_path / "x.compressed.ply").extra == {}


@pytest.mark.skipif(splat_transform() is None, reason="splat-transform not installed "
                    "(set HARNESS_SPLAT_TRANSFORM to its bin/cli.mjs or put it on PATH)")
def test_splat_transform_reads_what_we_write(tmp_path):
    ours = write_scene(source(), tmp_path / "ours.compressed.ply")
    run_splat_transform([str(ours), str(tmp_path / "back.ply")])
    theirs, decoded = read_ply(tmp_path / "back.ply"), read_ply(ours)
    assert len(theirs) == len(decoded) == 1000 and theirs.sh_degree == 3
    theirs = theirs.subset(match(decoded, theirs))  # the same rows, whatever order it wrote
    for attr in ("means", "scales_log", "sh_dc", "sh_rest"):
        np.testing.assert_allclose(getattr(theirs, attr), getattr(decoded, attr), atol=2e-6, err_msg=attr)
    assert quat_error(unit_quats(theirs), unit_quats(decoded)).max() < 1e-6
    assert np.abs(alpha(theirs) - alpha(decoded)).max() < 0.5 / 255  # only bytes 0/255 differ (clamped here)
    check_against_source(ours, decoded, source().subset(match(decoded, source())))


# ---------------------------------------------------------------------- bad files
def _compressed(tmp_path, edit=None) -> tuple:
    data, _ = encode_compressed_ply(random_scene(300, 1, seed=5))
    header, chunk, vertex, sh = data
    if edit:
        header, chunk, vertex, sh = edit(header, chunk, vertex, sh)
    path = tmp_path / "bad.compressed.ply"
    atomic_write_chunks(path, [header, chunk, vertex, sh])
    return path


def test_chunk_count_must_match_the_splat_count(capsys, tmp_path):
    path = _compressed(tmp_path, lambda h, c, v, s: (h.replace(b"element chunk 2", b"element chunk 1"), c[:1], v, s))
    assert_clean_error(capsys, path, "1 chunks for 300 splats", "ceil(300/256) = 2")


def test_truncated_file(capsys, tmp_path):
    path = _compressed(tmp_path)
    path.write_bytes(path.read_bytes()[:-100])
    assert_clean_error(capsys, path, "truncated", "'sh' row")


def test_vertex_count_larger_than_the_data(capsys, tmp_path):
    path = _compressed(tmp_path, lambda h, c, v, s: (h.replace(b"vertex 300", b"vertex 9000000"), c, v, s))
    assert_clean_error(capsys, path, "truncated", "of 9000000")


def test_non_finite_chunk_range_is_reported(capsys, tmp_path):
    def poison(h, c, v, s):
        c = c.copy()
        c[0, 0] = np.inf
        return h, c, v, s
    assert_clean_error(capsys, _compressed(tmp_path, poison), "NaN/inf values", "means")


def test_wrong_property_types_and_sh_counts(capsys, tmp_path):
    path = _compressed(tmp_path, lambda h, c, v, s: (h.replace(b"uint packed_rot", b"float packed_rot"), c, v, s))
    assert_clean_error(capsys, path, "packed_rotation is missing or not a uint")
    path = _compressed(tmp_path, lambda h, c, v, s: (h.replace(b"property uchar f_rest_8\n", b""),
                                                     c, v, s.reshape(300, 9)[:, :8].copy()))
    assert_clean_error(capsys, path, "sh element has 8 properties")
