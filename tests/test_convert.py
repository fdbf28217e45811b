"""`harness convert` and the writers it shares with `prune` (harness/io/writers.py):

* round trips: write -> our reader -> equal within the format's quantisation (.ply: equal; .spz: the
  bounds of tests/test_formats_spz.py, which independent writers' files meet too; compressed.ply and
  .splat have their own writer tests in test_formats_compressed_ply.py / test_splat_io.py);
* our .spz decodes to exactly what gaussforge's (v2, v3, v4) and splat-transform's (v4) files of the
  same source decode to: the same encoder;
* third-party readers (splat-transform, gsply, gaussforge, spz-js, plyfile) read what we write and get
  what we get; they live in $FORMATS_TOOLS (default ~/.cache/harness/format-tools, installed by
  tests/fixtures/formats/regenerate.sh); each test skips, saying which, when its reader is absent;
* the command: formats by name, refusals before any work, JSON report.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from harness.cli import main
from harness.core.errors import InputError
from harness.io.ply import read_ply
from harness.io.scenes import load_scene, write_scene
from harness.io.spz import read_spz
from harness.io.spz_write import encode_spz, fractional_bits, write_spz
from tests.formats_support import FIXTURES, alpha, match, quat_error, source, splat_transform, unit_quats
from tests.scene_factory import random_scene
from tests.test_formats_spz import check_against_source as spz_within_quantisation

TOOLS = Path(os.environ.get("FORMATS_TOOLS", Path.home() / ".cache" / "harness" / "format-tools"))
VENV_PY = TOOLS / "venv" / "bin" / "python"
SPZJS = TOOLS / "node" / "node_modules" / "spz-js"
HERE = Path(__file__).resolve().parent / "fixtures" / "formats"


def _convert(capsys, *argv) -> tuple[int, str, str]:
    status = main(["convert", *map(str, argv)])
    out = capsys.readouterr()
    return status, out.out, out.err


# ------------------------------------------------------------------------------------ round trips
def test_ply_round_trip_is_exact(tmp_path, capsys):
    scene = random_scene(200, 3, seed=4, extra=True)
    write_scene(scene, tmp_path / "a.ply", comments=["kept"])
    status, out, _ = _convert(capsys, tmp_path / "a.ply", tmp_path / "b.ply")
    assert status == 0 and "lossless" in out
    a, b = read_ply(tmp_path / "a.ply"), read_ply(tmp_path / "b.ply")
    for attr in ("means", "scales_log", "quats", "opacity_logit", "sh_dc", "sh_rest"):
        assert np.array_equal(getattr(a, attr), getattr(b, attr)), attr
    assert a.extra.keys() == b.extra.keys() and all(np.array_equal(a.extra[k], b.extra[k]) for k in a.extra)
    assert list(b.meta.comments) == ["kept"]


@pytest.mark.parametrize("version", [2, 3, 4])
@pytest.mark.parametrize("sh0", [False, True])
def test_spz_round_trip_within_quantisation(tmp_path, version, sh0):
    src = source(sh0)
    write_spz(src, tmp_path / "x.spz", version)
    decoded = read_spz(tmp_path / "x.spz")
    assert len(decoded) == len(src) and decoded.sh_degree == src.sh_degree
    spz_within_quantisation(decoded, src, version, "niantic")  # file order = scene order


@pytest.mark.parametrize("fixture", ["grape_1k.gf.v2.spz", "grape_1k.gf.v3.spz", "grape_1k.gf.v4.spz",
                                     "grape_1k.st3.v4.spz", "grape_1k_sh0.gf.v3.spz", "grape_1k_sh0.st3.v4.spz"])
def test_spz_decodes_like_independent_writers_files(tmp_path, fixture):
    """gaussforge 0.6.0 and splat-transform 3.7.0 (Niantic's encoder) wrote these from the same source."""
    src = source(fixture.startswith("grape_1k_sh0"))
    write_spz(src, tmp_path / "ours.spz", int(fixture.split(".v")[1][0]))
    ours, theirs = read_spz(tmp_path / "ours.spz"), read_spz(FIXTURES / fixture)
    theirs = theirs.subset(np.argsort(match(theirs, src)))
    for attr in ("means", "scales_log", "quats", "opacity_logit", "sh_dc", "sh_rest"):
        assert np.array_equal(getattr(ours, attr), getattr(theirs, attr)), attr


@pytest.mark.parametrize("version", [2, 3, 4])
def test_spz_reencoding_a_decoded_file_gives_its_bytes(version):
    from harness.io.spz_write import encode_streams

    first = read_spz_bytes(encode_spz(source(), version))
    again = encode_streams(first, version)[1]
    original = encode_streams(source(), version)[1]
    for i, name in enumerate(("positions", "alphas", "colours", "scales", "rotations", "sh")):
        if name == "rotations":  # re-normalising a decoded quaternion may move one 9/8-bit step
            a, b = (np.frombuffer(x, np.uint8).astype(int) for x in (again[i], original[i]))
            assert np.mean(a != b) < 0.05
        else:
            assert again[i] == original[i], name


def read_spz_bytes(chunks) -> object:
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "x.spz"
        path.write_bytes(b"".join(chunks))
        return read_spz(path)


def test_spz_fractional_bits_shrink_for_large_scenes(tmp_path):
    scene = random_scene(50, 1, seed=2)
    scene.means[0] = (3000.0, -1.0, 2.0)  # beyond 12 fractional bits (2048)
    assert fractional_bits(scene.means) == 11 and fractional_bits(source().means) == 12
    write_spz(scene, tmp_path / "big.spz")
    assert np.abs(read_spz(tmp_path / "big.spz").means - scene.means).max() <= 0.5 / 2048 + 1e-4
    scene.means[0, 0] = 2.0 ** 23
    with pytest.raises(InputError, match="24-bit fixed point"):
        encode_spz(scene)
    with pytest.raises(InputError, match="0 splats"):
        encode_spz(scene.subset(np.zeros(len(scene), bool)))


def test_spz_rotation_magnitude_never_spills_into_the_sign_bit():
    scene = random_scene(4, 0, seed=1)
    scene.quats[:] = (0.70710677, 0.70710677, 0.0, 0.0)  # two equal largest components
    write = encode_spz(scene, 3)
    decoded = read_spz_bytes(write)
    assert quat_error(unit_quats(decoded), unit_quats(scene)).max() < 2e-3


def test_equal_scenes_give_equal_files(tmp_path):
    for name in ("a.spz", "b.spz"):
        write_spz(source(), tmp_path / name, 3)
    assert (tmp_path / "a.spz").read_bytes() == (tmp_path / "b.spz").read_bytes()


# ------------------------------------------------------------------------------ third-party readers
def _same_decoding(ours, theirs, quat_tol=1e-5):
    """What a third-party reader decoded from our file (``theirs``) against our own decoding."""
    assert len(theirs) == len(ours)
    theirs = theirs.subset(match(ours, theirs))  # the same rows, whatever order it wrote
    np.testing.assert_allclose(theirs.means, ours.means, atol=1e-6)
    np.testing.assert_allclose(theirs.scales_log, ours.scales_log, atol=1e-5)
    np.testing.assert_allclose(theirs.sh_dc, ours.sh_dc, atol=1e-5)
    if theirs.sh_rest.size or ours.sh_rest.size:
        np.testing.assert_allclose(theirs.sh_rest, ours.sh_rest, atol=1e-6)
    assert quat_error(unit_quats(theirs), unit_quats(ours)).max() <= quat_tol
    assert np.abs(alpha(theirs) - alpha(ours)).max() <= 0.5 / 255  # bytes 0/255: clamped differently


def _ours(tmp_path, name, **options):
    path = write_scene(source(), tmp_path / name, **options)
    return path, load_scene(path)


def _splat_transform():
    found = splat_transform()
    if found:
        return found
    cli = TOOLS / "node3" / "node_modules" / "@playcanvas" / "splat-transform" / "bin" / "cli.mjs"
    return ["node", str(cli)] if cli.is_file() and shutil.which("node") else None


@pytest.mark.skipif(_splat_transform() is None, reason="splat-transform 3.7.0 not installed (npm; "
                    "$FORMATS_TOOLS/node3 or HARNESS_SPLAT_TRANSFORM, see tests/fixtures/formats/regenerate.sh)")
@pytest.mark.parametrize("name, options, quat_tol", [
    ("x.ply", {}, 1e-6), ("x.compressed.ply", {}, 1e-6), ("x.spz", {"spz_version": 4}, 1e-6),
    ("x.spz", {"spz_version": 3}, 1e-6),
    ("x.splat", {}, 1 / 127.5),  # splat-transform decodes rotation bytes on another scale before normalising
    ("x.sog", {}, 1e-6), ("meta.json", {}, 1e-6),
])
def test_splat_transform_reads_what_we_write(tmp_path, name, options, quat_tol):
    path, ours = _ours(tmp_path, name, **options)
    subprocess.run([*_splat_transform(), "-q", "-w", str(path), str(tmp_path / "back.ply")], check=True,
                   capture_output=True, timeout=120)
    _same_decoding(ours, read_ply(tmp_path / "back.ply"), quat_tol)


@pytest.mark.skipif(not VENV_PY.is_file(), reason=f"no {VENV_PY} with gsply 0.4.6 and gaussforge 0.6.0 (PyPI; "
                    "see tests/fixtures/formats/regenerate.sh)")
@pytest.mark.parametrize("reader, name, options, fmt, quat_tol", [
    ("gsply", "x.spz", {"spz_version": 4}, None, 1e-6), ("gsply", "x.spz", {"spz_version": 3}, None, 1e-6),
    ("gsply", "x.compressed.ply", {}, None, 1e-6),
    ("gaussforge", "x.spz", {"spz_version": 2}, "spz", 1e-4), ("gaussforge", "x.spz", {"spz_version": 3}, "spz", 1e-6),
    ("gaussforge", "x.spz", {"spz_version": 4}, "spz", 1e-6), ("gaussforge", "x.splat", {}, "splat", 1e-6),
    ("gaussforge", "x.compressed.ply", {}, "compressed.ply", 1e-6),
])
def test_python_readers_read_what_we_write(tmp_path, reader, name, options, fmt, quat_tol):
    path, ours = _ours(tmp_path, name, **options)
    subprocess.run([str(VENV_PY), str(HERE / "read_with.py"), reader, str(path), str(tmp_path / "back.ply"),
                    *([fmt] if fmt else [])], check=True, capture_output=True, timeout=120)
    _same_decoding(ours, read_ply(tmp_path / "back.ply"), quat_tol)


@pytest.mark.skipif(
    not (SPZJS.is_dir() and shutil.which("node")),
    reason=f"spz-js 1.2.5 not installed in {SPZJS.parent} (npm; see tests/fixtures/formats/regenerate.sh)",
)
def test_spz_js_reads_our_version_2(tmp_path):
    """spz-js 1.2.5 reads spz v2 only (its loader refuses v3 and v4): --spz-version 2 is for it."""
    path, ours = _ours(tmp_path, "x.spz", spz_version=2)
    (tmp_path / "node_modules").symlink_to(SPZJS.parent)  # node resolves packages next to the script
    shutil.copy(HERE / "spzjs_read.mjs", tmp_path)
    subprocess.run(["node", str(tmp_path / "spzjs_read.mjs"), str(path), str(tmp_path / "back.ply")], check=True,
                   capture_output=True, timeout=120)
    _same_decoding(ours, read_ply(tmp_path / "back.ply"))


def test_plyfile_reads_our_ply_and_compressed_ply(tmp_path):
    from plyfile import PlyData

    for name in ("x.ply", "x.compressed.ply"):
        path, _ = _ours(tmp_path, name)
        data = PlyData.read(str(path))
        assert data["vertex"].count == 1000
    assert {p.name for p in PlyData.read(str(tmp_path / "x.ply"))["vertex"].properties} >= {"x", "f_dc_0", "rot_3"}


# ---------------------------------------------------------------------------------------- command
@pytest.mark.parametrize(
    "name, label",
    [
        ("o.ply", "INRIA 3DGS .ply"),
        ("o.compressed.ply", "PlayCanvas compressed.ply"),
        ("o.splat", "antimatter15 .splat"),
        ("o.spz", "Niantic .spz v4"),
        ("o.sog", "PlayCanvas SOG (bundle)"),
        ("meta.json", "PlayCanvas SOG (folder)"),
    ],
)
def test_convert_writes_the_format_the_name_asks_for(tmp_path, capsys, name, label):
    status, out, err = _convert(capsys, HERE / "grape_1k.ply", tmp_path / name, "--json")
    assert status == 0, err
    report = json.loads(out)
    assert report["output"]["format"] == label and report["output"]["splats"] == 1000
    assert report["lossless"] == (name == "o.ply") and (report["loses"] is None) == (name == "o.ply")
    written = [tmp_path / name] if name != "meta.json" else sorted(tmp_path.iterdir())  # the folder: meta + textures
    assert report["output"]["bytes"] == sum(f.stat().st_size for f in written)
    assert len(load_scene(tmp_path / name)) == 1000


@pytest.mark.parametrize("name, phrase", [
    ("lod-meta.json", "streamed SOG is read but not written"), ("x-lod-meta.json", "streamed SOG is read"),
    ("o.spx", "did you mean '.spz'"), ("o", "files without an extension"), ("o.ksplat", "not written"),
])
def test_unwritable_names_are_refused_before_reading(tmp_path, capsys, name, phrase):
    status, out, err = _convert(capsys, tmp_path / "missing.ply", tmp_path / name)
    assert status == 2 and phrase in err and len(err.splitlines()) == 1 and not (tmp_path / name).exists()


def test_convert_refuses_its_input_and_missing_folders(tmp_path, capsys):
    src = tmp_path / "a.ply"
    write_scene(random_scene(10, 0, seed=1), src)
    before = src.read_bytes()
    status, _, err = _convert(capsys, src, src)
    assert status == 2 and "would overwrite the input" in err and src.read_bytes() == before
    status, _, err = _convert(capsys, src, tmp_path / "no" / "b.spz")
    assert status == 2 and "output folder does not exist" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.ply"]


@pytest.mark.parametrize("name", ["o.splat", "o.spz", "o.compressed.ply", "o.sog"])
def test_the_lossy_note_names_only_what_this_scene_loses(tmp_path, capsys, name):
    plain = random_scene(300, 0, seed=2)
    write_scene(plain, tmp_path / "sh0.ply")
    write_scene(random_scene(300, 2, seed=2, extra=True), tmp_path / "rich.ply", comments=["made here"])
    notes = {}
    for src in ("sh0", "rich"):
        status, out, _ = _convert(capsys, tmp_path / f"{src}.ply", tmp_path / f"{src}-{name}", "--json")
        assert status == 0
        notes[src] = json.loads(out)["loses"]
    assert "SH" not in notes["sh0"] and "extra" not in notes["sh0"] and "comments" not in notes["sh0"]
    assert "SH" in notes["rich"] and "extra properties dropped (nx, ny, nz)" in notes["rich"]
    assert ("header comments dropped" in notes["rich"]) == (name != "o.compressed.ply")  # compressed.ply keeps them
    status, out, _ = _convert(capsys, tmp_path / "sh0.ply", tmp_path / "again.ply")
    assert status == 0 and "\n  lossless\n" in out and "lossy:" not in out


@pytest.mark.parametrize("name, moved", [("o.compressed.ply", 1e30), ("o.spz", 1e6)])
def test_outliers_that_move_the_other_splats_are_warned_about(tmp_path, capsys, caplog, name, moved):
    """One far splat widens the quantisation range of the others (compressed.ply: its chunk; spz:
    the fractional bits); SOG's log-scaled range keeps them within the bound, .ply is exact."""
    scene = random_scene(100, 0, seed=1)
    write_scene(scene, tmp_path / "quiet.ply")
    assert _convert(capsys, tmp_path / "quiet.ply", tmp_path / f"quiet-{name}")[0] == 0
    assert "warning" not in caplog.text
    scene.means[0] = (moved, 0.0, 0.0)
    write_scene(scene, tmp_path / "far.ply")
    for out, warned in ((name, True), ("o.sog", False), ("o.ply", False)):
        caplog.clear()
        assert _convert(capsys, tmp_path / "far.ply", tmp_path / f"far-{out}")[0] == 0
        assert ("splats are stored up to" in caplog.text) == warned, (out, caplog.text)
    back = load_scene(tmp_path / f"far-{name}")  # what the warning says did happen: splats really moved
    near = back.means[np.abs(back.means).max(1) < 10].astype(np.float64)
    gap = np.linalg.norm(near[:, None] - scene.means[1:][None].astype(np.float64), axis=2).min(1)
    assert gap.max() > 1e-3 * np.linalg.norm(np.ptp(scene.means[1:], axis=0))


def test_spz_version_must_be_an_integer(tmp_path):
    import harness

    with pytest.raises(InputError, match="spz_version: must be an integer .* got '4' \\(str\\)"):
        harness.save(source(), tmp_path / "x.spz", spz_version="4")
    assert not (tmp_path / "x.spz").exists()
    harness.save(source(), tmp_path / "x.spz", spz_version=np.int64(3))  # a numpy integer is an integer
    assert (tmp_path / "x.spz").read_bytes()[:2] == b"\x1f\x8b"  # v3: one gzip stream


def test_prune_writes_every_format_and_ratio_zero_scores_nothing(tmp_path, capsys, monkeypatch):
    src = HERE / "grape_1k.ply"
    for name in ("p.spz", "p.splat", "p.compressed.ply", "p.sog"):
        assert main(["prune", str(src), str(tmp_path / name), "--ratio", "0.3", "--method", "opacity"]) == 0
        assert len(load_scene(tmp_path / name)) == 700
    capsys.readouterr()
    import methods.registry as registry

    spec = registry.get_pruner("betadesc")
    monkeypatch.setattr(type(spec), "score", lambda *a, **k: pytest.fail("ratio 0 must not score"))
    assert main(["prune", str(src), str(tmp_path / "same.ply"), "--ratio", "0", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["tau"] is None and report["scored"] is False and report["removed"] == 0
    assert main(["prune", str(src), str(tmp_path / "same2.ply"), "--keep", "1"]) == 0
    out = capsys.readouterr().out
    assert "tau = none" in out and "harness convert" in out
    assert np.array_equal(read_ply(tmp_path / "same.ply").means, read_ply(src).means)
