"""Every number finite or refused: cameras are checked where they are made, scenes beyond what the
float32 pipeline holds are refused where they enter rendering, a metric's NaN is never a score, a
view that shows nothing is never a perfect one, tracking refuses a NaN group, and every JSON the
product writes is strict."""

from __future__ import annotations

import ast
import json
import math
from pathlib import Path

import numpy as np
import pytest

import harness
from harness.core.cameras import COORD_MAX, Camera, CameraError
from harness.core.errors import InputError
from harness.core.extent import blur, extent_problem
from harness.core.scene import GaussianScene
from tests.scene_factory import random_scene

REPO = Path(__file__).resolve().parent.parent


def _scaled(scene: GaussianScene, k: float) -> GaussianScene:
    return GaussianScene.from_arrays(scene.means * k, scene.scales_log + np.log(k), scene.quats, scene.opacity_logit,
                                     scene.sh_dc)


@pytest.mark.parametrize("m, phrase", [
    (lambda m: m.__setitem__((0, 3), np.nan), "must be finite"),
    (lambda m: m.__setitem__((0, 0), 2.0), "not a rigid transform"),
    (lambda m: m.__setitem__((2, 3), 1e13), r"beyond the ±1e\+12"),
])
def test_a_camera_is_checked_where_it_is_made(m, phrase):
    w2c = np.eye(4)
    m(w2c)
    with pytest.raises(CameraError, match=phrase):
        Camera(w2c, 50.0, 50.0, 16.0, 16.0, 32, 32, "c")
    with pytest.raises(CameraError, match="no direction"):
        Camera.look_at((1.0, 2.0, 3.0), (1.0, 2.0, 3.0))
    with pytest.raises(CameraError, match="fx, fy, cx, cy must be finite"):
        Camera(np.eye(4), math.nan, 50.0, 16.0, 16.0, 32, 32)


def test_rigs_are_exact_at_any_scale_the_pipeline_holds():
    """Fitting a rig once probed from the target plus one unit: at 1e17 that is the target itself
    (NaN cameras). The probe is scale-free now: a scene × 1e11 gets the rig × 1e11."""
    s = random_scene(400, 0, seed=2)
    base, far = (harness.cameras(x, rig="orbit", n_test=2, longest_side=32) for x in (s, _scaled(s, 1e11)))
    for a, b in zip(base, far):
        np.testing.assert_allclose(b.center, a.center * 1e11, rtol=1e-6)
        np.testing.assert_allclose(b.rotation, a.rotation, atol=1e-9)


def test_a_scene_beyond_the_pipelines_range_is_refused_where_it_would_be_rendered(tmp_path):
    s = _scaled(random_scene(300, 0, seed=1), 1e18)
    assert "300 of 300 splats lie beyond ±1e+12" in extent_problem(s)
    for call in (lambda: harness.cameras(s), lambda: harness.render(s, [Camera(np.eye(4), 9.0, 9.0, 4.0, 4.0, 8, 8)])):
        with pytest.raises(harness.HarnessError, match="the float32 render pipeline"):
            call()
    one = random_scene(100, 0, seed=1)
    one.means[7] = (1e30, 0.0, 0.0)
    assert "1 of 100 splats lie beyond" in extent_problem(one) and "first: row 7" in extent_problem(one)
    assert extent_problem(_scaled(one.subset(np.arange(100) != 7), COORD_MAX / 10)) is None
    harness.save(one, tmp_path / "one.ply")  # not rendering: written as it is


def test_a_scene_far_from_the_origin_for_its_size_is_refused():
    """float32 spaces numbers near 10⁵ 2⁻⁷ apart: a scene of radius ~1 there renders blurred, at 10⁸
    its centres round to a few points (a radius of 0, which the splats' own size stands in for)."""
    s = random_scene(300, 0, seed=1)

    def moved(k):
        return GaussianScene.from_arrays(s.means + np.float32(k), s.scales_log, s.quats, s.opacity_logit, s.sh_dc)

    assert blur(s) < 1e-6 and extent_problem(moved(1e2)) is None
    for k in (1e5, 1e8):
        assert "float32's steps there are" in extent_problem(moved(k))
    with pytest.raises(harness.HarnessError, match="move the scene near the origin"):
        harness.render(moved(1e8), [Camera(np.eye(4), 9.0, 9.0, 4.0, 4.0, 8, 8)])
    assert extent_problem(s.subset(np.arange(300) == 0)) is None  # one splat: its size is its radius
    assert blur(s.subset(np.zeros(300, bool))) == 0.0


def test_a_metric_that_gives_nan_is_refused_naming_it():
    from harness.metrics.suite import checked

    assert checked({"psnr": math.inf, "ssim": 1.0, "other": math.nan}, "x") == {"psnr": math.inf, "ssim": 1.0,
                                                                             "other": math.nan}
    with pytest.raises(InputError, match="metric ssim: gave nan for two images"):
        checked({"ssim": math.nan}, "two images")
    with pytest.raises(InputError, match="metric lpips: gave inf"):
        checked({"lpips": math.inf}, "two images")


@pytest.mark.parametrize("side, names, phrase", [
    (4, "mpeg", "4x4 pixels is too small for rgb_ivssim, yuv_ivssim"),
    (2, "yuv_ssim", "2x2 pixels is too small for yuv_ssim"),
    (5, "mpeg-qmiv", "5x5 pixels is too small for yuv_ssim_qmiv, yuv_ssim_om_qmiv"),
])
def test_the_mpeg_set_refuses_images_smaller_than_its_windows(side, names, phrase):
    rng = np.random.default_rng(0)
    a, b = rng.random((side, side, 3)).astype(np.float32), rng.random((side, side, 3)).astype(np.float32)
    with pytest.raises(InputError, match=phrase):
        harness.compare(a, b, names)
    assert math.isfinite(harness.compare(a, b, "rgb_psnr,yuv_psnr")["rgb_psnr"])  # PSNRs take any size
    big = rng.random((8, 8, 3)).astype(np.float32)
    assert all(math.isfinite(v) for v in harness.compare(big, big[::-1].copy(), "mpeg").values())


def test_a_view_that_shows_nothing_is_an_error_never_a_perfect_score(tmp_path, monkeypatch):
    """Renders of a view that sees no splat are identical (PSNR +inf, SSIM 1): the view's rows are
    errors naming it, not a perfect cell."""
    import yaml

    from harness.cli import main
    from harness.io.cameras import write_3dgs_cameras
    from harness.io.scenes import write_scene
    from harness.report.results import read_results

    monkeypatch.chdir(tmp_path)
    write_scene(random_scene(300, 0, seed=1), tmp_path / "s.ply")
    away = Camera.look_at((0.0, 0.0, 8.0), (0.0, 0.0, 20.0), width=32, height=24, name="away")
    write_3dgs_cameras([away, Camera.look_at((0.0, 0.0, 6.0), (0, 0, 0), width=32, height=24, name="at")],
                       tmp_path / "cams.json")
    cfg = {"name": "t", "output": "out", "ratios": [0.3], "methods": ["opacity"], "tables": [], "plots": [],
           "protocol": {"metrics": ["psnr"]},
           "scenes": [{"name": "s", "source": "s.ply", "cameras": {"path": "cams.json", "test_every": 1}}]}
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(cfg))
    assert main(["run", "c.yaml", "--cache", str(tmp_path / "cache")]) == 1
    df = read_results(tmp_path / "out")
    assert (df[df["view"] == "away"]["status"] == "error").all()
    errors = json.loads((tmp_path / "out" / "run.json").read_text())["errors"]
    assert any("view 'away' shows no splat" in e for e in errors)
    assert (df[df["view"] == "at"]["status"] == "ok").all()


def test_track_refuses_a_group_whose_metric_is_nan_on_every_view(tmp_path):
    import pandas as pd

    from harness.report import tracking
    from tests.stress.cases import _run_dir

    run = _run_dir(tmp_path)
    df = pd.read_parquet(run / "results.parquet")
    both = pd.concat([df.assign(ssim=np.nan), df.assign(method="random")])
    with pytest.raises(InputError, match="opacity.*SSIM column holds NaN"):
        tracking.summarize_groups(both)
    unmeasured = tracking.summarize_groups(both.assign(ssim=np.nan))  # no view measured it: not tracked
    assert all(g["ssim"] is None for g in unmeasured.values())


def test_diagnose_says_n_a_for_a_share_of_nothing():
    from methods.diagnose import Diagnosis, format_text

    text = format_text("s", 10, [Diagnosis("opacity", {}, 0.3, 3)])
    assert "nan" not in text and "significance n/a" in text


def _json_calls():
    for root in ("harness", "methods", "renderers"):
        for path in sorted((REPO / root).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                        and node.func.attr in ("dump", "dumps") and getattr(node.func.value, "id", None) == "json":
                    yield path.relative_to(REPO).as_posix(), node


#: JSON that is not the product's output: the stage cache's own entries (read back only by the
#: harness, whose checks refuse NaN and keep PSNR's +inf for identical renders) and the key text
#: hashed into cache keys; the benchmark probe's CPU seconds; parameters as text to match them; a
#: dict copied through JSON in memory
NOT_OUTPUT = {"harness/run/cache/stage_cache.py", "harness/benchmarks/study.py", "harness/study/reading_search.py",
              "harness/study/claim_cells.py"}


def test_every_json_the_product_writes_is_strict():
    """Python writes NaN and Infinity unless told not to: every ``json.dump(s)`` of the product passes
    ``allow_nan=False`` (or goes through :mod:`harness.core.jsonout`, which maps them to null)."""
    loose = [f"{path}:{node.lineno}" for path, node in _json_calls() if path not in NOT_OUTPUT
             and path != "harness/core/jsonout.py"
             and not any(k.arg == "allow_nan" and getattr(k.value, "value", True) is False for k in node.keywords)]
    assert not loose, f"json.dump(s) without allow_nan=False: {loose}"
