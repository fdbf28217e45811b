"""MPEG mpeg-gsc-metrics: the product (harness.metrics.mpeg) against the independent numpy
re-statement in tests/mpeg_reference.py — bit for bit (==), both modes, OM included — on synthetic
images and on real GL renders of luigi; plus the quantisation, padding and cap rules one by one."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from harness.cli import main
from harness.metrics import mpeg, mpeg_ssim
from harness.metrics.registry import expand, family_names
from harness.metrics.suite import MetricSuite, compare_images
from tests import mpeg_reference as ref

#: product key -> reference key
KEYS = {"rgb_psnr": "psnr_rgb_avg", "yuv_psnr": "psnr_yuv_avg", "yuv_ssim": "ssim_avg",
        "rgb_psnr_om": "psnr_rgb_om_avg", "yuv_psnr_om": "psnr_yuv_om_avg", "yuv_ssim_om": "ssim_om_avg",
        "occupancy": "occupancy", "mse_rgb": "mse_rgb", "mse_yuv": "mse_yuv", "psnr_yuv": "psnr_yuv",
        "ssim_yuv": "ssim", "ssim_yuv_om": "ssim_om", "mse_yuv_om": "mse_yuv_om",
        "rgb_ivssim": "rgb_ivssim", "yuv_ivssim": "yuv_ivssim"}


def _check_exact(a, b, mask, qmiv):
    got = mpeg.tool_metrics(a, b, mask, qmiv=qmiv)
    want = ref.mpeg_metrics(ref.quantize_render_to_u8(a) if a.dtype != np.uint8 else a,
                            ref.quantize_render_to_u8(b) if b.dtype != np.uint8 else b, mask, qmiv)
    for k, k2 in KEYS.items():
        assert np.array_equal(got[k], want[k2], equal_nan=True), (k, qmiv, got[k], want[k2])  # IV-SSIM: NaN < 8 px
    return got


def _pair(h, w, seed, noise=12):
    rng = np.random.default_rng(seed)
    a = rng.integers(0, 256, (h, w, 3)).astype(np.uint8)
    b = np.clip(a.astype(int) + rng.integers(-noise, noise + 1, a.shape), 0, 255).astype(np.uint8)
    return a, b


@pytest.mark.parametrize("qmiv", [False, True])
@pytest.mark.parametrize("shape", [(9, 7), (37, 23), (48, 64)])
def test_synthetic_bit_exact(shape, qmiv):
    a, b = _pair(*shape, seed=shape[0])
    mask = np.random.default_rng(3).random(shape) < 0.4
    for m in (None, mask, np.zeros(shape, bool)):
        _check_exact(a, b, m, qmiv)


def _object_on_black(h, w, seed):
    """A render-like pair: an object on black, the second with a patch of it changed and a corner
    of it removed; the mask is the object's occupancy plus a few lone pixels (windows the mask fills,
    touches, or barely touches)."""
    rng = np.random.default_rng(seed)
    a = np.zeros((h, w, 3), np.uint8)
    occ = np.zeros((h, w), bool)
    occ[h // 5:4 * h // 5, w // 4:3 * w // 4] = True
    a[occ] = rng.integers(0, 256, (int(occ.sum()), 3))
    b = a.copy()
    b[h // 3:h // 3 + 4, w // 3:w // 3 + 5] = rng.integers(0, 256, (4, 5, 3))
    b[h // 5:h // 5 + 3, w // 4:w // 4 + 3] = 0
    mask = occ.copy()
    mask[rng.integers(0, h, 4), rng.integers(0, w, 4)] = True
    return a, b, mask


@pytest.mark.parametrize("qmiv", [False, True])
@pytest.mark.parametrize("shape", [(40, 64), (67, 45), (12, 9)])
def test_partly_equal_images_bit_exact(shape, qmiv):
    """Equal windows are taken as exactly 1 and masked windows by their mask count: the values stay the tool's."""
    a, b, mask = _object_on_black(*shape, seed=sum(shape))
    for m in (None, mask, np.ones(shape, bool), np.zeros(shape, bool)):
        _check_exact(a, b, m, qmiv)
    _check_exact(a, a, mask, qmiv)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # the reference computes inf - inf
@pytest.mark.parametrize("value", [1e-200, 1e200, np.inf, np.nan])
def test_ssim_planes_with_extreme_equal_values(value):
    """Equal taps outside the normal range (tiny, huge, inf, NaN) are computed, not assumed to give 1."""
    rng = np.random.default_rng(5)
    a = rng.random((24, 30, 3)) * 255
    a[3, 4] = value
    b = a.copy()
    b[20, 26] += 3.0  # far from the extreme value: its windows are equal
    mask = rng.random((24, 30)) < 0.7
    full, om = mpeg_ssim.ssim_yuv(a, b, mask)
    for c in range(3):
        assert np.array_equal(full[c], ref.ssim_plane(a[..., c], b[..., c]), equal_nan=True), c
        assert np.array_equal(om[c], ref.ssim_plane_masked(a[..., c], b[..., c], mask), equal_nan=True), c


def test_float_renders_quantised_like_the_tool():
    # round half away from zero on c*255 in float32, then clamp (not truncation, not banker's rounding)
    vals = np.array([0.5 / 255, 1.5 / 255, 2.5 / 255, -0.2, 1.7, 254.5 / 255, np.nan], np.float32)
    img = np.repeat(vals[None, :, None], 3, axis=2)
    q = mpeg.quantize(img)[0, :, 0]
    p = vals * np.float32(255)
    expected = [int(np.clip(np.sign(x) * np.floor(abs(x) + 0.5), 0, 255)) if np.isfinite(x) else 0 for x in p]
    assert q.tolist() == expected
    assert q[:3].tolist() == [1, 2, 3]  # np.round would give 0, 2, 2
    below_half = np.nextafter(np.float32(0.5), np.float32(0))  # floor(p + 0.5) rounds this one up
    c = np.float32(below_half) / np.float32(255)
    assert np.float32(c) * np.float32(255) == below_half and mpeg.quantize(np.full((1, 1, 3), c, np.float32)).max() == 0
    k = np.arange(256, dtype=np.uint8)  # an 8-bit PNG read as k/255 comes back as k
    f = np.repeat((k.astype(np.float32) / np.float32(255))[None, :, None], 3, 2)
    assert np.array_equal(mpeg.quantize(f)[0, :, 0], k)
    rng = np.random.default_rng(0)
    x = rng.uniform(-0.1, 1.1, (64, 64, 3)).astype(np.float32)
    assert np.array_equal(mpeg.quantize(x), ref.quantize_render_to_u8(x))


def test_padding_quirks_exactly():
    """Tool rows: 5 rows above the last are row 0 again, left columns are column 5, right mirror."""
    img = np.arange(8 * 9, dtype=np.float64).reshape(8, 9)  # [row, col], row 0 = tool's first (bottom) row
    p = mpeg_ssim.pad_like_tool(img)
    assert p.shape == (18, 19)
    assert np.array_equal(p[5:13, 5:14], img)
    assert np.array_equal(p[13, 5:14], img[0]) and np.array_equal(p[17, 5:14], img[0])   # quirk: row 0
    assert np.array_equal(p[0, 5:14], img[0])                                           # replicate
    assert np.array_equal(p[5:13, 0], img[:, 5]) and np.array_equal(p[5:13, 4], img[:, 5])  # quirk: column 5
    assert np.array_equal(p[5:13, 14], img[:, 8]) and np.array_equal(p[5:13, 18], img[:, 4])  # mirror
    assert p[17, 0] == img[7, 5] and p[0, 18] == img[0, 4]  # corners: column rules, row clamped
    assert np.array_equal(p, ref._pad_like_tool(img))


def test_caps_and_identical_images():
    a, _ = _pair(20, 30, 1)
    r = mpeg.tool_metrics(a, a, None)
    assert r["rgb_psnr"] == r["yuv_psnr"] == 999.99 and r["psnr_rgb"] == [999.99] * 3
    assert r["yuv_ssim"] == 1.0
    b = a.copy()
    b[0, 0, 0] ^= 1  # one channel differs: QMIV averages capped PSNRs, MPEG averages MSEs
    q, d = mpeg.tool_metrics(a, b, None, qmiv=True), mpeg.tool_metrics(a, b, None)
    assert q["rgb_psnr"] > 600 and d["rgb_psnr"] < 100
    e = mpeg.tool_metrics(a, b, np.zeros(a.shape[:2]))  # empty mask: OM PSNRs 0, OM-SSIM 1, occupancy 0
    assert (e["rgb_psnr_om"], e["yuv_psnr_om"], e["occupancy"], e["yuv_ssim_om"]) == (0.0, 0.0, 0.0, 1.0)


def test_orientation_matters_for_ssim_only():
    a, b = _pair(40, 50, 2)
    up, down = mpeg.tool_metrics(a, b, None), mpeg.tool_metrics(a, b, None, rows_top_down=False)
    assert up["mse_rgb"] == down["mse_rgb"]
    assert up["yuv_ssim"] != down["yuv_ssim"]


def test_gcc_o3_rounding_option_is_within_a_micro_db():
    a, b = _pair(64, 64, 5)
    f, g = mpeg.tool_metrics(a, b, None), mpeg.tool_metrics(a, b, None, yuv_rounding="gcc-o3")
    want = ref.mpeg_metrics(a, b, None, False, compute_ivssim=False, yuv_rounding="gcc-o3")
    assert g["yuv_psnr"] == want["psnr_yuv_avg"]
    assert abs(f["yuv_psnr"] - g["yuv_psnr"]) < 1e-6


def test_registry_families():
    assert expand(["mpeg"]) == family_names("mpeg") == ("rgb_psnr", "yuv_psnr", "yuv_ssim", "rgb_psnr_om",
                                                 "yuv_psnr_om", "yuv_ssim_om", "rgb_ivssim", "yuv_ivssim")
    assert expand(["3dgs"]) == ("psnr", "ssim", "lpips")
    assert all(n.endswith("_qmiv") for n in expand(["mpeg-qmiv"]))


# ------------------------------------------------------------------------------------------ real renders
@pytest.fixture(scope="module")
def luigi_renders():
    """GL renders (256 px) of luigi and of luigi with 30 % of its splats removed, with alphas."""
    from harness.io import datasets
    from harness.io.scenes import load_scene
    from harness.views.rigs import scene_rig
    from renderers.gl import GLRenderer, GLUnavailable

    path = datasets.scene_path("luigi")
    if not path.exists():
        pytest.skip(f"luigi not fetched ({path}); run `harness fetch`")
    scene = load_scene(path)
    views = scene_rig("luigi", scene, "default", n_train=0, n_test=2, longest_side=256, aspect=None, seed=0)
    keep = np.random.default_rng(0).random(len(scene)) > 0.3
    gl = GLRenderer()
    try:
        out = [(gl.render_with_alpha(scene, cam), gl.render_with_alpha(scene.subset(keep), cam)) for cam in views.test]
    except GLUnavailable as err:
        pytest.skip(f"no EGL OpenGL context: {err}")
    finally:
        gl.close()
    return out


@pytest.mark.gl
@pytest.mark.data
@pytest.mark.parametrize("qmiv", [False, True])
def test_real_renders_bit_exact(luigi_renders, qmiv):
    for (a, alpha_a), (b, alpha_b) in luigi_renders:
        mask = mpeg.occupancy_mask(alpha_a, alpha_b)
        assert 0.05 < mask.mean() < 0.95  # the object covers part of the view
        full = _check_exact(a, b, None, qmiv)
        om = _check_exact(a, b, mask, qmiv)
        assert 20 < full["rgb_psnr"] < 80 and 0.5 < full["yuv_ssim"] < 1
        assert om["rgb_psnr_om"] < full["rgb_psnr"]  # errors live where the object is
        assert om["occupancy"] == 100.0 * mask.sum() / mask.size


@pytest.mark.gl
@pytest.mark.data
def test_suite_and_compare_use_the_union_mask(luigi_renders, tmp_path, capsys):
    (a, alpha_a), (b, alpha_b) = luigi_renders[0]
    names = expand(["mpeg"])
    suite = MetricSuite(names=names)
    suite.reference("v", a, alpha=alpha_a)
    got = suite.score("v", b, alpha=alpha_b)
    want = mpeg.tool_metrics(a, b, mpeg.occupancy_mask(alpha_a, alpha_b))
    assert {k: got[k] for k in names} == {k: want[k] for k in names}
    assert got["occupancy"] == want["occupancy"]
    np.save(tmp_path / "a.npy", a)
    np.save(tmp_path / "b.npy", b)
    Image.fromarray((mpeg.occupancy_mask(alpha_a, alpha_b) * 255).astype(np.uint8)).save(tmp_path / "m.png")
    for qmiv in (False, True):
        argv = ["compare", str(tmp_path / "a.npy"), str(tmp_path / "b.npy"), "--metrics", "mpeg", "--json",
                "--mask", str(tmp_path / "m.png")] + (["--qmiv"] if qmiv else [])
        assert main(argv) == 0
        obj = json.loads(capsys.readouterr().out)
        want = ref.mpeg_metrics(ref.quantize_render_to_u8(a), ref.quantize_render_to_u8(b),
                                mpeg.occupancy_mask(alpha_a, alpha_b), qmiv)
        for k in ("rgb_psnr", "yuv_psnr", "yuv_ssim", "rgb_psnr_om", "yuv_psnr_om", "yuv_ssim_om", "occupancy"):
            assert obj[k] == want[KEYS[k]], (k, qmiv)
        assert obj["rgb_ivssim"] == want["rgb_ivssim"] and obj["yuv_ivssim"] == want["yuv_ivssim"]
        assert obj.get("mode") == ("qmiv" if qmiv else None)


def test_compare_cli_keys(tmp_path, capsys):
    a, b = _pair(30, 40, 7)
    Image.fromarray(a).save(tmp_path / "a.png")
    Image.fromarray(b).save(tmp_path / "b.png")
    assert main(["compare", str(tmp_path / "a.png"), str(tmp_path / "b.png"), "--metrics", "mpeg", "--json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert set(obj) == set(family_names("mpeg"))  # no occupancy without --mask; all-ones mask: OM = full frame
    assert obj["rgb_psnr_om"] == obj["rgb_psnr"] == ref.mpeg_metrics(a, b, None)["psnr_rgb_avg"]
    assert main(["compare", str(tmp_path / "a.png"), str(tmp_path / "a.png"), "--metrics", "mpeg", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["rgb_psnr"] == 999.99
    assert main(["compare", str(tmp_path / "a.png"), str(tmp_path / "b.png"), "--metrics", "nope"]) == 2
    assert "unknown metric" in capsys.readouterr().err


def test_compare_images_keeps_uint8():
    a, b = _pair(16, 16, 9)
    got = compare_images(a, b, names=family_names("mpeg"))
    assert got["yuv_psnr"] == ref.mpeg_metrics(a, b, None)["psnr_yuv_avg"]
