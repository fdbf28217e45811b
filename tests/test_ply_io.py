"""INRIA .ply reader/writer, checked against plyfile (an independent PLY implementation)."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from harness.core.scene import GaussianScene
from harness.io import datasets
from harness.io.files import atomic_write_chunks as atomic_write
from harness.io.ply import read_ply, read_ply_header, write_ply
from tests.scene_factory import random_scene

CORE = ("means", "scales_log", "quats", "opacity_logit", "sh_dc", "sh_rest")
INRIA_ORDER = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]


def assert_bit_identical(a: GaussianScene, b: GaussianScene) -> None:
    for name in CORE:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype == np.float32 and x.shape == y.shape, name
        assert x.tobytes() == y.tobytes(), name
    assert list(a.extra) == list(b.extra)
    for name in a.extra:
        assert a.extra[name].dtype == b.extra[name].dtype and a.extra[name].tobytes() == b.extra[name].tobytes()


def inria_columns(scene: GaussianScene) -> dict[str, np.ndarray]:
    """Property name -> values, computed here from the documented layout (f_rest_{c*K + k})."""
    k = scene.sh_rest.shape[1]
    cols = {axis: scene.means[:, i] for i, axis in enumerate("xyz")}
    cols.update({f"f_dc_{c}": scene.sh_dc[:, c] for c in range(3)})
    cols.update({f"f_rest_{c * k + j}": scene.sh_rest[:, j, c] for c in range(3) for j in range(k)})
    cols["opacity"] = scene.opacity_logit
    cols.update({f"scale_{i}": scene.scales_log[:, i] for i in range(3)})
    cols.update({f"rot_{i}": scene.quats[:, i] for i in range(4)})
    return cols


def write_with_plyfile(path, cols: dict[str, np.ndarray], order: list[str], *, text=False, byte_order="<"):
    table = np.empty(len(next(iter(cols.values()))), dtype=[(n, cols[n].dtype.str[1:]) for n in order])
    for n in order:
        table[n] = cols[n]
    PlyData([PlyElement.describe(table, "vertex")], text=text, byte_order=byte_order).write(str(path))


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
@pytest.mark.parametrize("extra", [False, True])
def test_write_read_round_trip_is_bit_exact(tmp_path, degree, extra):
    scene = random_scene(257, degree, seed=degree, extra=extra)
    scene.extra["label"] = np.arange(257, dtype=np.uint8)  # a non-float extra keeps its type
    write_ply(scene, tmp_path / "a.ply")
    back = read_ply(tmp_path / "a.ply")
    assert back.sh_degree == degree
    assert_bit_identical(scene, back)
    write_ply(back, tmp_path / "b.ply")
    assert (tmp_path / "a.ply").read_bytes() == (tmp_path / "b.ply").read_bytes()


@pytest.mark.parametrize("fmt", ["binary_little_endian", "binary_big_endian", "ascii"])
@pytest.mark.parametrize("all_float32", [True, False])  # the reader's matrix path and its per-field path
def test_reads_any_property_order_and_encoding_written_by_plyfile(tmp_path, fmt, all_float32):
    scene = random_scene(40, 2, seed=7)
    cols = inria_columns(scene)
    cols["nx"] = np.linspace(-1, 1, 40).astype(np.float32)
    cols["density"] = np.linspace(0, 9, 40).astype(np.float32 if all_float32 else np.float64)
    order = list(cols)
    np.random.default_rng(1).shuffle(order)
    path = tmp_path / "shuffled.ply"
    write_with_plyfile(path, cols, order, text=fmt == "ascii", byte_order=">" if "big" in fmt else "<")
    back = read_ply(path)
    assert_bit_identical(GaussianScene(scene.means, scene.scales_log, scene.quats, scene.opacity_logit,
                                       scene.sh_dc, scene.sh_rest, dict(back.extra)), back)
    extras_in_file_order = [n for n in order if n in ("nx", "density")]
    assert list(back.extra) == extras_in_file_order
    assert back.extra["density"].dtype == cols["density"].dtype
    assert np.array_equal(back.extra["density"], cols["density"])
    assert back.extra["nx"].dtype.byteorder in ("=", "|") and np.array_equal(back.extra["nx"], cols["nx"])


def test_written_file_has_inria_layout_and_values_plyfile_reads(tmp_path):
    scene = random_scene(30, 3, seed=2, extra=True)
    write_ply(scene, tmp_path / "out.ply")
    data = PlyData.read(str(tmp_path / "out.ply"))
    assert data.text is False and data.byte_order == "<"
    names = [p.name for p in data["vertex"].properties]
    expected = (INRIA_ORDER + [f"f_rest_{i}" for i in range(45)] + ["opacity"]
                + [f"scale_{i}" for i in range(3)] + [f"rot_{i}" for i in range(4)])
    assert names == expected
    for name, values in inria_columns(scene).items():
        assert data["vertex"][name].tobytes() == values.tobytes(), name
    assert all(p.val_dtype == "f4" for p in data["vertex"].properties)


def test_normals_are_not_invented_and_other_extras_follow_rotation(tmp_path):
    scene = random_scene(5, 0, seed=4)
    scene.extra["filter_3D"] = np.ones(5, np.float32)
    write_ply(scene, tmp_path / "o.ply")
    names = [p for p, _ in read_ply_header(tmp_path / "o.ply").elements[0].properties]
    assert names[:6] == ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2"]
    assert names[-5:] == ["rot_0", "rot_1", "rot_2", "rot_3", "filter_3D"]


def test_sibr_layout_is_the_fixed_62_float_struct(tmp_path):
    scene = random_scene(25, 1, seed=12)
    scene.extra["filter_3D"] = np.ones(25, np.float32)
    write_ply(scene, tmp_path / "sibr.ply", sibr_layout=True)
    header = read_ply_header(tmp_path / "sibr.ply")
    names = [p for p, _ in header.elements[0].properties]
    assert names == (INRIA_ORDER + [f"f_rest_{i}" for i in range(45)] + ["opacity"]
                     + [f"scale_{i}" for i in range(3)] + [f"rot_{i}" for i in range(4)])
    body = (tmp_path / "sibr.ply").read_bytes()[header.data_offset:]
    rows = np.frombuffer(body, "<f4").reshape(25, 62)  # the struct SIBR copies the rows into
    np.testing.assert_array_equal(rows[:, 3:6], 0.0)
    np.testing.assert_array_equal(rows[:, 0:3], scene.means)
    back = read_ply(tmp_path / "sibr.ply")
    assert back.sh_degree == 3 and not back.sh_rest[:, 3:].any()
    assert back.sh_rest[:, :3].tobytes() == scene.sh_rest.tobytes()
    assert back.quats.tobytes() == scene.quats.tobytes()


def test_subset_keeps_every_kept_value_bit_exact(tmp_path):
    scene = random_scene(500, 3, seed=9, extra=True)
    write_ply(scene, tmp_path / "full.ply")
    keep = np.sort(np.random.default_rng(0).choice(500, 321, replace=False))
    write_ply(read_ply(tmp_path / "full.ply").subset(keep), tmp_path / "pruned.ply")
    full = PlyData.read(str(tmp_path / "full.ply"))["vertex"].data
    pruned = PlyData.read(str(tmp_path / "pruned.ply"))["vertex"].data
    assert pruned.dtype == full.dtype
    assert pruned.tobytes() == full[keep].tobytes()


def test_header_comments_are_written_and_read(tmp_path):
    write_ply(random_scene(3), tmp_path / "c.ply", comments=["made by a test", "camera 1 2 3"])
    assert read_ply_header(tmp_path / "c.ply").comments == ["made by a test", "camera 1 2 3"]


def test_elements_before_vertex_are_skipped(tmp_path):
    scene = random_scene(12, 1, seed=5)
    cols = inria_columns(scene)
    table = np.empty(12, dtype=[(n, "f4") for n in cols])
    for n, v in cols.items():
        table[n] = v
    meta = np.array([(1.5, 7)], dtype=[("a", "f8"), ("b", "i4")])
    PlyData([PlyElement.describe(meta, "camera"), PlyElement.describe(table, "vertex")]).write(str(tmp_path / "e.ply"))
    assert_bit_identical(scene, read_ply(tmp_path / "e.ply"))


def test_atomic_write_leaves_no_partial_file(tmp_path):
    target = tmp_path / "x.ply"
    target.write_bytes(b"old")

    def chunks():
        yield b"new header"
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        atomic_write(target, chunks())
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.ply"]


def test_empty_scene_round_trips(tmp_path):
    scene = random_scene(0, 1)
    write_ply(scene, tmp_path / "empty.ply")
    assert len(read_ply(tmp_path / "empty.ply")) == 0


@pytest.mark.data
@pytest.mark.parametrize("name", ["grape-small", "luigi"])
def test_real_ply_scenes_round_trip(tmp_path, name):
    path = datasets.scene_path(name)
    if not path.exists():
        pytest.skip(f"{name} not available at {path} (run `harness fetch` / provide ../shared/data)")
    before = hashlib.sha256(path.read_bytes()).hexdigest()
    scene = read_ply(path)
    write_ply(scene, tmp_path / "rt.ply")
    assert_bit_identical(scene, read_ply(tmp_path / "rt.ply"))
    reference = PlyData.read(str(path))["vertex"]
    for prop in reference.properties:
        written = PlyData.read(str(tmp_path / "rt.ply"))["vertex"][prop.name]
        assert written.tobytes() == reference[prop.name].astype("<f4").tobytes(), prop.name
    assert hashlib.sha256(path.read_bytes()).hexdigest() == before
    if name == "luigi":  # already in the standard order: the output is the same file
        assert (tmp_path / "rt.ply").read_bytes() == path.read_bytes()
