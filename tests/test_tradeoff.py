"""`harness bench tradeoff`: Pareto flags, removed-set Jaccard, downsampling, and a quick end-to-end run."""

from __future__ import annotations

import json

import numpy as np
import pytest

from harness.study.bench.tradeoff import LIMITS, markdown, within
from harness.study.tradeoff_knobs import (
    Row,
    downsample,
    pareto_front,
    removed_jaccard,
)


def test_pareto_front_by_hand():
    pts = [(1.0, 0.0), (0.5, 0.2), (0.6, 0.3), (0.2, 0.5), (0.2, 0.6), (2.0, 0.0)]
    # (0.6, 0.3) is dominated by (0.5, 0.2); (0.2, 0.6) by (0.2, 0.5); (2.0, 0.0) by (1.0, 0.0)
    assert pareto_front(pts) == [True, True, False, True, False, False]
    assert pareto_front([(1.0, 1.0), (1.0, 1.0)]) == [True, True]  # equal points do not dominate


def test_removed_jaccard():
    a = np.arange(10, dtype=float)            # removes 0, 1, 2 at ratio 0.3
    assert removed_jaccard(a, a) == 1.0
    b = a.copy()
    b[[0, 9]] = b[[9, 0]]                     # removes 1, 2, 3
    assert removed_jaccard(a, b) == pytest.approx(2 / 4)
    assert removed_jaccard(a, -a) == 0.0      # removes 7, 8, 9


def test_downsample_is_an_area_average():
    img = np.zeros((64, 32, 3), np.float32)
    img[::2] = 1.0                            # alternating rows average to 0.5
    small = downsample(img, 32)
    assert small.shape == (32, 16, 3)
    np.testing.assert_allclose(small, 0.5, atol=1e-6)
    assert downsample(img, 128) is img        # never upsampled


def test_cheapest_within_tolerance():
    rows = [Row("res", "1024px", True, 2.0, 2.0, {"|dPSNR|": 0.0}),
            Row("res", "512px", False, 1.0, 0.5, {"|dPSNR|": LIMITS["|dPSNR|"] / 2}),
            Row("res", "256px", False, 0.5, 0.2, {"|dPSNR|": LIMITS["|dPSNR|"] * 3})]
    md, picks = markdown("t", rows, [True, True, True])
    assert picks == {"res": "512px"} and "**1024px** (ref)" in md
    assert not within({"1-jaccard@0.3": 0.2}) and within({"1-jaccard@0.3": 0.05, "other": 9.0})


@pytest.mark.slow
@pytest.mark.data
@pytest.mark.gl
@pytest.mark.weights
def test_quick_run_writes_table_json_and_plot(tmp_path):
    from harness.cli import main
    from harness.io import datasets

    if not (datasets.scene_path("grape-small")).is_file():
        pytest.skip("grape_small.ply missing from the shared data folder")
    try:
        from harness.metrics.lpips_weights import load_backbone

        load_backbone(None)
    except Exception as err:  # noqa: BLE001 - any missing-weights error means skip
        pytest.skip(f"LPIPS weights unavailable: {err}")
    assert main(["bench", "tradeoff", "--scene", "grape-small", "--quick", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "tradeoff.json").read_text())
    fams = {r["family"] for r in data["rows"]}
    assert fams == {"voxel", "max_nn", "resolution", "lpips_input", "lpips_precision", "renderer"}
    for r in data["rows"]:
        if r["reference"]:  # the reference setting has zero error against itself, and is Pareto-optimal
            assert r["pareto"] and all(v in (0.0, None) for v in r["errors"].values())
        assert r["cpu_s"] >= 0 and r["wall_s"] > 0
    gl = next(r for r in data["rows"] if r["setting"] == "gl")
    assert gl["errors"]["image PSNR vs float64 (dB)"] > 45  # GL agrees with the float64 rasterizer
    assert (tmp_path / "tradeoff_pareto.png").stat().st_size > 10_000
    assert "Cheapest within tolerance" in (tmp_path / "tradeoff.md").read_text()
