"""PlayCanvas SOG v2 reader: synthetic SOG sets written here from the format description
(lossless WebP via Pillow), expected values computed per splat with scalar math, plus the real
playbot LOD set."""

from __future__ import annotations

import io
import json
import math
import zipfile

import numpy as np
import pytest
from PIL import Image

from harness.cli import main
from harness.core.errors import InputError
from harness.io import datasets
from harness.io.ply import read_ply, write_ply
from harness.io.sog import lod_levels, read_sog

SQRT2 = math.sqrt(2.0)


def save_webp(path, pixels: np.ndarray, lossless=True) -> None:
    Image.fromarray(np.ascontiguousarray(pixels, np.uint8), "RGBA").save(path, "WEBP", lossless=lossless,
                                                                         exact=True, quality=100 if lossless else 60)


def texture(rows: np.ndarray, width: int) -> np.ndarray:
    """Rows (n, 4) placed row-major in a width-wide image, padded with zeros."""
    height = -(-len(rows) // width)
    out = np.zeros((height * width, 4), np.uint8)
    out[: len(rows)] = rows
    return out.reshape(height, width, 4)


def encode_quat(q) -> tuple[int, int, int, int]:
    """Smallest-three packing as the SOG writer does it (scalar code, truncating bytes)."""
    q = [v / math.sqrt(sum(c * c for c in q)) for v in q]
    m = max(range(4), key=lambda i: abs(q[i]))
    if q[m] < 0:
        q = [-v for v in q]
    rest = [q[i] * SQRT2 for i in range(4) if i != m]
    return (*(int(255 * (v * 0.5 + 0.5)) for v in rest), 252 + m)


class SogSpec:
    """Random codes for ``n`` splats and what they must decode to."""

    def __init__(self, n: int, seed: int, bands: int = 0, palette: int = 70):
        rng = np.random.default_rng(seed)
        self.n, self.bands, self.palette = n, bands, palette
        self.mins, self.maxs = [-1.5, -0.2, 0.0], [2.0, 0.7, 0.0]  # z range empty: span taken as 1
        self.q16 = rng.integers(0, 65536, size=(n, 3))
        self.unit_quats = rng.normal(size=(n, 4))
        self.quat_codes = np.array([encode_quat(q) for q in self.unit_quats], np.uint8)
        self.scale_book = np.sort(rng.normal(-5, 2, 256)).astype(np.float32)
        self.dc_book = np.sort(rng.normal(0, 1.5, 256)).astype(np.float32)
        self.scale_codes = rng.integers(0, 256, size=(n, 3))
        self.dc_codes = rng.integers(0, 256, size=(n, 3))
        self.alpha = rng.integers(0, 256, size=n)
        self.k = {0: 0, 1: 3, 2: 8, 3: 15}[bands]
        self.sh_book = np.sort(rng.normal(0, 0.3, 256)).astype(np.float32)
        self.centroids = rng.integers(0, 256, size=(palette, self.k, 3))
        self.labels = rng.integers(0, palette, size=n)
        if n > 3:
            self.labels[3] = palette + 5  # out of the palette: zero coefficients

    def write(self, folder, width=8) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        full = lambda rgb, a: np.concatenate([rgb, np.broadcast_to(a, (self.n, 1))], axis=1)
        save_webp(folder / "means_l.webp", texture(full(self.q16 & 255, 255), width))
        save_webp(folder / "means_u.webp", texture(full(self.q16 >> 8, 255), width))
        save_webp(folder / "quats.webp", texture(self.quat_codes, width))
        save_webp(folder / "scales.webp", texture(full(self.scale_codes, 255), width))
        save_webp(folder / "sh0.webp", texture(full(self.dc_codes, self.alpha[:, None]), width))
        meta = {"version": 2, "count": self.n,
                "means": {"mins": self.mins, "maxs": self.maxs, "files": ["means_l.webp", "means_u.webp"]},
                "scales": {"codebook": self.scale_book.tolist(), "files": ["scales.webp"]},
                "quats": {"files": ["quats.webp"]},
                "sh0": {"codebook": self.dc_book.tolist(), "files": ["sh0.webp"]}}
        if self.bands:
            cent = np.zeros((-(-self.palette // 64) * 64, self.k, 4), np.uint8)
            cent[: self.palette, :, :3] = self.centroids
            cent[:, :, 3] = 255
            save_webp(folder / "shN_centroids.webp", cent.reshape(-1, 64 * self.k, 4))
            lab = np.stack([self.labels & 255, self.labels >> 8, 0 * self.labels, 255 + 0 * self.labels], 1)
            save_webp(folder / "shN_labels.webp", texture(lab, width))
            meta["shN"] = {"count": self.palette, "bands": self.bands, "codebook": self.sh_book.tolist(),
                           "files": ["shN_centroids.webp", "shN_labels.webp"]}
        (folder / "meta.json").write_text(json.dumps(meta))

    def expected_mean(self, i: int, axis: int) -> float:
        span = (self.maxs[axis] - self.mins[axis]) or 1.0
        v = self.mins[axis] + span * self.q16[i, axis] / 65535
        return math.copysign(math.exp(abs(v)) - 1, v)


def test_synthetic_sog_decodes_every_field(tmp_path):
    spec = SogSpec(37, seed=1, bands=1)
    spec.write(tmp_path / "s")
    scene = read_sog(tmp_path / "s")
    assert len(scene) == 37 and scene.sh_degree == 1
    assert lod_levels(tmp_path / "s") is None
    for i in range(37):
        for axis in range(3):
            assert scene.means[i, axis] == pytest.approx(spec.expected_mean(i, axis), rel=1e-6, abs=1e-7)
        assert list(scene.scales_log[i]) == [spec.scale_book[c] for c in spec.scale_codes[i]]
        assert list(scene.sh_dc[i]) == [spec.dc_book[c] for c in spec.dc_codes[i]]
        a = min(max(spec.alpha[i] / 255, 1e-6), 1 - 1e-6)
        assert scene.opacity_logit[i] == pytest.approx(math.log(a / (1 - a)), rel=1e-6, abs=1e-6)
        for k in range(spec.k):
            for c in range(3):
                want = 0.0 if spec.labels[i] >= spec.palette else spec.sh_book[spec.centroids[spec.labels[i], k, c]]
                assert scene.sh_rest[i, k, c] == want


def test_quaternions_unpack_to_the_encoded_rotation(tmp_path):
    spec = SogSpec(200, seed=2)
    spec.write(tmp_path / "q", width=16)
    quats = read_sog(tmp_path / "q").quats.astype(np.float64)
    np.testing.assert_allclose(np.linalg.norm(quats, axis=1), 1.0, atol=1e-6)
    truth = spec.unit_quats / np.linalg.norm(spec.unit_quats, axis=1, keepdims=True)
    truth *= np.sign(truth[np.arange(200), np.abs(truth).argmax(1)])[:, None]  # largest made positive
    assert np.abs(quats - truth).max() < 2 * SQRT2 / 255  # byte truncation of the three smallest
    assert (quats[np.arange(200), spec.quat_codes[:, 3] - 252] > 0).all()


def test_hand_picked_quaternion_codes(tmp_path):
    spec = SogSpec(4, seed=3)
    spec.quat_codes = np.array(
        [[128, 128, 128, 252], [0, 255, 128, 254], [255, 255, 255, 255], [9, 9, 9, 17]], np.uint8
    )
    spec.write(tmp_path / "h")
    q = read_sog(tmp_path / "h").quats
    s = (128 / 255 * 2 - 1) / SQRT2
    np.testing.assert_allclose(q[0], [math.sqrt(1 - 3 * s * s), s, s, s], rtol=1e-6)
    lo, hi, mid = -1 / SQRT2, 1 / SQRT2, s
    np.testing.assert_allclose(q[1], [lo, hi, math.sqrt(max(0.0, 1 - lo * lo - hi * hi - mid * mid)), mid], atol=1e-6)
    np.testing.assert_allclose(q[2], [hi, hi, hi, 0.0], atol=1e-6)  # 1 - 3/2 < 0 -> largest clamps to 0
    np.testing.assert_array_equal(q[3], [1, 0, 0, 0])  # invalid tag -> identity


def write_lod_set(root) -> tuple[SogSpec, SogSpec]:
    a, b = SogSpec(10, seed=4, bands=2), SogSpec(4, seed=5, bands=2)
    a.write(root / "0_0")
    b.write(root / "1_0")
    tree = {"children": [  # children listed out of offset order on purpose
        {"lods": {"0": {"file": 0, "offset": 6, "count": 4}, "1": {"file": 1, "offset": 2, "count": 2},
                  "2": {"file": 1, "offset": 3, "count": 1}}},
        {"lods": {"0": {"file": 0, "offset": 0, "count": 6}, "1": {"file": 1, "offset": 0, "count": 2},
                  "2": {"file": 0, "offset": 2, "count": 3}}},  # level 2: parts of both files
    ]}
    (root / "lod-meta.json").write_text(json.dumps(
        {"lodLevels": 3, "filenames": ["0_0/meta.json", "1_0/meta.json"], "tree": tree}))
    return a, b


def test_lod_levels_select_rows_by_tree_references(tmp_path, capsys):
    write_lod_set(tmp_path)
    level0, level1 = read_sog(tmp_path / "0_0" / "meta.json"), read_sog(tmp_path / "1_0" / "meta.json")
    assert lod_levels(tmp_path) == 3
    level2 = [level0.subset([2, 3, 4]), level1.subset([3])]
    level2 = type(level0)(*(np.concatenate([getattr(p, a) for p in level2]) for a in
                            ("means", "scales_log", "quats", "opacity_logit", "sh_dc", "sh_rest")))
    for lod, want in ((None, level0), (0, level0), (1, level1), (2, level2)):
        got = read_sog(tmp_path, lod)
        assert got.means.tobytes() == want.means.tobytes() and got.sh_rest.tobytes() == want.sh_rest.tobytes()
    every = read_sog(tmp_path / "lod-meta.json", "all")
    assert len(every) == 18 and every.sh_degree == 2
    assert every.quats[10:14].tobytes() == level1.quats.tobytes()
    with pytest.raises(InputError, match="LOD level 3 does not exist"):
        read_sog(tmp_path, 3)
    assert main(["info", str(tmp_path / "lod-meta.json"), "--lod", "all", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["splats"], info["lod"], info["format"]) == (18, "all", "sog")
    assert main(["info", str(tmp_path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["lod"] == 0


def test_sog_bundle_reads_like_the_folder(tmp_path):
    SogSpec(20, seed=6, bands=3).write(tmp_path / "f")
    with zipfile.ZipFile(tmp_path / "b.sog", "w") as z:
        for f in (tmp_path / "f").iterdir():
            z.write(f, f.name)
    a, b = read_sog(tmp_path / "f"), read_sog(tmp_path / "b.sog")
    for attr in ("means", "quats", "scales_log", "opacity_logit", "sh_dc", "sh_rest"):
        assert getattr(a, attr).tobytes() == getattr(b, attr).tobytes()


def test_pillow_lossless_webp_is_exact_and_lossy_is_rejected(tmp_path):
    pixels = np.random.default_rng(7).integers(0, 256, size=(9, 11, 4), dtype=np.uint8)
    buf = io.BytesIO()
    Image.fromarray(pixels, "RGBA").save(buf, "WEBP", lossless=True, exact=True)
    assert np.array_equal(np.asarray(Image.open(io.BytesIO(buf.getvalue())).convert("RGBA")), pixels)
    SogSpec(16, seed=8).write(tmp_path / "l")
    save_webp(tmp_path / "l" / "scales.webp", texture(np.full((16, 4), 100), 8), lossless=False)
    with pytest.raises(InputError, match="lossy WebP"):
        read_sog(tmp_path / "l")


def test_broken_sog_sets_raise_input_errors(tmp_path):
    SogSpec(16, seed=9).write(tmp_path / "m")
    (tmp_path / "m" / "quats.webp").unlink()
    with pytest.raises(InputError, match="quats.webp: missing"):
        read_sog(tmp_path / "m")
    SogSpec(16, seed=9).write(tmp_path / "c")
    meta = json.loads((tmp_path / "c" / "meta.json").read_text())
    meta["count"] = 999
    (tmp_path / "c" / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(InputError, match="fewer than the 999 splats"):
        read_sog(tmp_path / "c")


@pytest.mark.data
def test_real_playbot_lod_set(tmp_path):
    root = datasets.scene_path("playbot")
    if not root.exists():
        pytest.skip(f"shared data folder lacks {root}")
    assert lod_levels(root) == 7
    scene = read_sog(root)
    assert len(scene) == 500_000 and scene.sh_degree == 2
    np.testing.assert_allclose(np.linalg.norm(scene.quats, axis=1), 1.0, atol=1e-5)
    meta = json.loads((root / "0_0" / "meta.json").read_text())
    inv = lambda v: np.sign(v) * np.expm1(np.abs(v))
    np.testing.assert_allclose(scene.means.min(0), inv(np.array(meta["means"]["mins"])), rtol=1e-6)
    np.testing.assert_allclose(scene.means.max(0), inv(np.array(meta["means"]["maxs"])), rtol=1e-6)
    counts = [len(read_sog(root, level)) for level in range(1, 7)]
    assert counts == [250_000, 125_000, 31_000, 8_406, 3_000, 1_873]
    write_ply(scene, tmp_path / "playbot.ply")  # round trip: SOG -> .ply -> identical arrays
    back = read_ply(tmp_path / "playbot.ply")
    for attr in ("means", "quats", "scales_log", "opacity_logit", "sh_dc", "sh_rest"):
        assert getattr(back, attr).tobytes() == getattr(scene, attr).tobytes(), attr


def _rezip(src_folder, bundle, replace: dict[str, bytes]) -> None:
    """``bundle``: the files of ``src_folder`` deflated, some replaced."""
    with zipfile.ZipFile(bundle, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(src_folder.iterdir()):
            z.writestr(f.name, replace.get(f.name, f.read_bytes()))


def test_bundle_members_are_refused_past_their_cap_before_inflating(tmp_path):
    """A texture may take 8 bytes per allowed pixel + 1 MiB; a JSON member the JSON cap (64 MiB). A
    few-hundred-KB .sog whose member inflates to 64 MiB (or a 65 MiB meta.json) is refused from
    the zip directory, nothing inflated; a texture file on disk the same way."""
    SogSpec(20, seed=6).write(tmp_path / "f")
    quats = (tmp_path / "f" / "quats.webp").read_bytes()
    _rezip(tmp_path / "f", tmp_path / "t.sog", {"quats.webp": quats + bytes(64 << 20)})
    assert (tmp_path / "t.sog").stat().st_size < 1 << 20
    with pytest.raises(InputError, match=r"t.sog:quats.webp: is 67,\d+,\d+ bytes, over the 1,\d+,\d+ allowed for "
                                         "a texture"):
        read_sog(tmp_path / "t.sog")
    meta = (tmp_path / "f" / "meta.json").read_bytes()
    _rezip(tmp_path / "f", tmp_path / "j.sog", {"meta.json": meta + b" " * (65 << 20)})
    with pytest.raises(InputError, match="j.sog:meta.json: is 68,.* over the 67,108,864 allowed for a JSON file"):
        read_sog(tmp_path / "j.sog")
    (tmp_path / "f" / "quats.webp").write_bytes(quats + bytes(2 << 20))
    with pytest.raises(InputError, match="quats.webp: is 2,.* allowed for a texture"):
        read_sog(tmp_path / "f")
