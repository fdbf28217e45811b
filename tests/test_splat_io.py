"""antimatter15 .splat reader/writer: hand-made records, encode/decode error bounds, real files."""

from __future__ import annotations

import numpy as np
import pytest

from harness.core.scene import SH_C0, normalized_quats, sigmoid
from harness.io import datasets
from harness.io.ply import read_ply, write_ply
from harness.io.splat import SPLAT_RECORD, encode_splat, read_splat, write_splat
from tests.scene_factory import random_scene


def _record(pos, scale, rgba, rot) -> bytes:
    rec = np.zeros(1, SPLAT_RECORD)
    rec["pos"], rec["scale"], rec["rgba"], rec["rot"] = pos, scale, rgba, rot
    return rec.tobytes()


def test_hand_made_records_decode_to_the_documented_parameters(tmp_path):
    path = tmp_path / "two.splat"
    path.write_bytes(_record((1.0, -2.0, 3.5), (0.5, 1.0, 2.0), (255, 128, 0, 255), (255, 128, 128, 128))
                     + _record((0.0, 0.0, 0.0), (1e-3, 1e-3, 1e-3), (64, 64, 64, 0), (128, 0, 255, 128)))
    s = read_splat(path)
    assert len(s) == 2 and s.sh_degree == 0 and s.extra == {}
    np.testing.assert_array_equal(s.means[0], [1.0, -2.0, 3.5])
    np.testing.assert_allclose(s.scales_log[0], np.log([0.5, 1.0, 2.0]), rtol=1e-6)
    np.testing.assert_allclose(s.sh_dc[0], [(1.0 - 0.5) / SH_C0, (128 / 255 - 0.5) / SH_C0, -0.5 / SH_C0], rtol=1e-6)
    np.testing.assert_allclose(s.quats[0], [127 / 128, 0, 0, 0])
    np.testing.assert_allclose(s.quats[1], [0, -1, 127 / 128, 0])
    # A = 255 / 0 are clamped a quarter step inside (0, 1), so the logits are finite
    np.testing.assert_allclose(sigmoid(s.opacity_logit.astype(np.float64)), [1 - 0.25 / 255, 0.25 / 255], rtol=1e-5)
    assert np.isfinite(s.opacity_logit).all()


def test_encode_decode_error_is_within_quantisation(tmp_path):
    scene = random_scene(2000, 2, seed=11)
    write_splat(scene, tmp_path / "r.splat")
    back = read_splat(tmp_path / "r.splat")
    assert back.sh_degree == 0
    np.testing.assert_array_equal(back.means, scene.means)
    np.testing.assert_allclose(back.scales_log, scene.scales_log, atol=1e-5)
    rgb = np.clip(0.5 + SH_C0 * scene.sh_dc.astype(np.float64), 0, 1)
    got_rgb = 0.5 + SH_C0 * back.sh_dc.astype(np.float64)
    assert np.abs(got_rgb - rgb).max() <= 0.5 / 255 + 1e-6
    alpha = sigmoid(scene.opacity_logit.astype(np.float64))
    got_alpha = sigmoid(back.opacity_logit.astype(np.float64))
    assert np.abs(got_alpha - alpha).max() <= 0.5 / 255 + 1e-6
    q = normalized_quats(scene.quats.astype(np.float64))
    err = np.abs(back.quats - q)
    clipped = q * 128 + 128 > 255  # a component near +1 saturates at byte 255 = 127/128
    assert err[~clipped].max() <= 0.5 / 128 + 1e-6
    assert err[clipped].max(initial=0) <= 1 / 128 + 1e-6


def test_decoded_file_reencodes_to_its_own_bytes(tmp_path):
    rng = np.random.default_rng(3)
    rec = np.zeros(500, SPLAT_RECORD)
    rec["pos"] = rng.normal(size=(500, 3))
    rec["scale"] = np.exp(rng.normal(-4, 1, size=(500, 3)))
    rec["rgba"] = rng.integers(0, 256, size=(500, 4))
    q = rng.normal(size=(500, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    rec["rot"] = np.clip(np.rint(q * 128 + 128), 0, 255)  # as a writer of unit quaternions stores them
    (tmp_path / "in.splat").write_bytes(rec.tobytes())
    again = encode_splat(read_splat(tmp_path / "in.splat"))
    assert again["pos"].tobytes() == rec["pos"].tobytes()
    assert again["rgba"].tobytes() == rec["rgba"].tobytes()
    np.testing.assert_allclose(again["scale"], rec["scale"], rtol=1e-6)
    assert np.abs(again["rot"].astype(int) - rec["rot"]).max() <= 1  # encoder renormalises


@pytest.mark.data
@pytest.mark.parametrize("name", ["bonsai-7k-mini", "bonsai-7k"])
def test_real_splat_scenes_read_and_round_trip_through_ply(tmp_path, name):
    path = datasets.scene_path(name)
    if not path.exists():
        pytest.skip(f"{name} not fetched ({path} missing; run `harness fetch --scenes`)")
    scene = read_splat(path)
    assert len(scene) == datasets.SCENES[name].splats
    raw = np.fromfile(path, SPLAT_RECORD)
    assert encode_splat(scene)["rgba"].tobytes() == raw["rgba"].tobytes()
    write_ply(scene, tmp_path / "rt.ply")
    back = read_ply(tmp_path / "rt.ply")
    for attr in ("means", "scales_log", "quats", "opacity_logit", "sh_dc", "sh_rest"):
        assert getattr(back, attr).tobytes() == getattr(scene, attr).tobytes(), attr
