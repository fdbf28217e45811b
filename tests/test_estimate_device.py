"""`harness plan --estimate` on one GPU: from a device calibration when there is one, a plain "not
measured" when there is none; and `harness bench calibrate` writing that calibration (run here on
the CPU)."""

from __future__ import annotations

import json

import pytest

from harness.cli import main
from harness.run.estimate import IMAGE_OVERHEAD_S, STARTUP_S, estimate
from harness.run.estimate_device import CALIBRATION, GPU_UNITS, one_gpu
from harness.run.unit_costs import COVERAGE_UNITS
from tests.test_plan import _tiny, _units


def _calibration(folder, **units):
    doc = {"device": "cuda", "device_name": "Test GPU", "units": {k: units.get(k, 0.0) for k in GPU_UNITS}}
    (folder / CALIBRATION).write_text(json.dumps(doc))


def test_without_a_calibration_the_gpu_time_is_not_measured(tmp_path):
    config, infos = _tiny(tmp_path)
    got = one_gpu(config, infos, tmp_path, _units(), 16, 0.75)
    assert got == {"measured": False, "note": got["note"]} and "not measured" in got["note"]
    (tmp_path / CALIBRATION).write_text('{"units": {"render_px": "fast"}}')  # unusable: the same
    assert not one_gpu(config, infos, tmp_path, _units(), 16, 0.75)["measured"]


def test_gpu_stages_are_serial_at_the_gpu_units_and_cpu_scoring_is_shared(tmp_path):
    config, infos = _tiny(tmp_path)
    cpu = _units(render_splat=1.0, render_px=1.0, lpips_px=1.0, ssim_px=1.0, psnr_px=1.0, read_splat=1e-3,
                 select_splat=1e-3, score_splat={"opacity": 1e-2})
    _calibration(tmp_path)  # a GPU that costs nothing: only the CPU's stages are left
    zero = one_gpu(config, infos, tmp_path, cpu, 4, 0.5)
    cpu_est = estimate(config, infos, cpu).stages
    assert zero["stages_s"]["load"] == pytest.approx(cpu_est["load"].core_s)
    assert zero["stages_s"]["prune"] == pytest.approx(cpu_est["prune"].core_s)
    # opacity on 100 and 200 splats at 1e-2 s per splat, on 4 cores at 50 %
    assert zero["stages_s"]["score"] == pytest.approx(STARTUP_S + 300 * 1e-2 / (4 * 0.5))
    assert zero["stages_s"]["render+metrics"] == pytest.approx(STARTUP_S + 48 * IMAGE_OVERHEAD_S)  # per image
    _calibration(tmp_path, psnr_px=1e-6, ssim_px=2e-6, render_px=1e-6)
    one = one_gpu(config, infos, tmp_path, cpu, 4, 0.5)
    _calibration(tmp_path, psnr_px=2e-6, ssim_px=4e-6, render_px=2e-6)
    two = one_gpu(config, infos, tmp_path, cpu, 4, 0.5)
    for stage in ("render_ref", "render+metrics"):
        grow = two["stages_s"][stage] - one["stages_s"][stage]
        assert grow == pytest.approx(one["stages_s"][stage] - zero["stages_s"][stage]) and grow > 0
    # 12 reference renders of 64×48 at 1e-6 s per pixel
    assert one["stages_s"]["render_ref"] == pytest.approx(STARTUP_S + 12 * 64 * 48 * 1e-6)
    assert one["wall_s"] == pytest.approx(sum(one["stages_s"].values())) and one["device"] == "Test GPU"


def test_plan_prints_the_one_gpu_line(tmp_path, capsys):
    config, _ = _tiny(tmp_path)
    (tmp_path / "tiny.yaml").write_text(json.dumps(config.raw))
    bench = tmp_path / "bench"
    bench.mkdir()
    assert main(["plan", str(tmp_path / "tiny.yaml"), "--estimate", "--bench", str(bench)]) == 0
    assert "**On one GPU: not measured.**" in capsys.readouterr().out
    _calibration(bench, render_px=1e-7, psnr_px=1e-8)
    assert main(["plan", str(tmp_path / "tiny.yaml"), "--estimate", "--bench", str(bench), "--out",
                 str(tmp_path / "p.json")]) == 0
    assert "**On one GPU (Test GPU) with 16 cores:" in capsys.readouterr().out
    assert json.loads((tmp_path / "p.json").read_text())["one_gpu"]["measured"]


@pytest.mark.slow
@pytest.mark.gl
@pytest.mark.data
def test_calibrate_on_the_cpu_writes_every_unit(tmp_path):
    from harness.metrics import lpips_weights as lw
    from harness.run.calibrate import _scene

    if _scene()[1] is None or not lw.weights_available():
        pytest.skip("no real scene or LPIPS weights here (harness fetch)")
    assert main(["bench", "calibrate", "--device", "cpu", "--size", "192", "--repeats", "1",
                 "--out", str(tmp_path)]) == 0
    doc = json.loads((tmp_path / "calibrate-cpu.json").read_text())
    assert set(doc["units"]) == set(GPU_UNITS) | {"pack_splat", *COVERAGE_UNITS}
    assert all(v >= 0 for v in doc["units"].values()) and doc["units"]["draw_splat"] > 0
    assert 0.9 < doc["seen"]["visible"] <= doc["seen"]["front"] == 1.0 and doc["seen"]["overdraw"] > 1
    assert doc["units"]["lpips_px"] > doc["units"]["psnr_px"] > 0 and doc["seconds"]["ssim"]["batch"] == 1
