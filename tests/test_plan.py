"""`harness plan`: exact work counts of a cold run, cost scaling, assumed scenes, bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from harness.cli import main
from harness.io.ply import write_ply
from harness.run.config import parse_config
from harness.run.estimate import (
    POOL_START_S,
    Assumptions,
    Estimate,
    SceneInfo,
    Stage,
    estimate,
    scene_info,
)
from harness.run.unit_costs import UnitCosts, from_bench
from tests.scene_factory import random_scene

REPO = Path(__file__).resolve().parent.parent


def _units(**over) -> UnitCosts:
    u = dict(render_splat=0.0, render_px=0.0, lpips_px=0.0, lpips_ref_px=0.0, ssim_px=0.0, psnr_px=0.0,
             select_splat=0.0, read_splat=0.0, score_splat={"opacity": 0.0}, aware={"lightgs": (1.0, "views")})
    u.update(over)
    return UnitCosts(**u)


def _tiny(tmp_path, metrics=("3dgs",), extra_methods=()):
    """2 scenes (100 and 200 splats), opacity + camera-aware lightgs, ratios 0.1/0.3, protocols
    rig + shifted, 3 held-out and 4 training views per scene at 64 px."""
    for name, n in (("a", 100), ("b", 200)):
        write_ply(random_scene(n, seed=n), tmp_path / f"{name}.ply")
    doc = {
        "protocol": {"longest_side": 64, "n_test": 3, "n_train": 4, "metrics": list(metrics)},
        "protocols": ["rig", "shifted"],
        "ratios": [0.1, 0.3],
        "scenes": [{"name": "a", "source": str(tmp_path / "a.ply")}, {"name": "b", "source": str(tmp_path / "b.ply")}],
        "methods": ["opacity", "lightgs", *extra_methods],
    }
    config = parse_config(doc, str(tmp_path / "tiny.yaml"))
    return config, [scene_info(s, config, Assumptions()) for s in config.scenes]


def _units_of(est: Estimate) -> dict:
    return {k: s.units for k, s in est.stages.items()}


def test_counts_of_a_tiny_config_are_exact(tmp_path):
    config, infos = _tiny(tmp_path)
    assert [(i.status, i.splats, len(i.views), len(i.train), i.views[0]) for i in infos] == [
        ("read", [100], 6, 4, (64, 48)), ("read", [200], 6, 4, (64, 48))]  # 3 views × 2 protocols
    est = estimate(config, infos, None)
    # load 2 frames; score 2 scenes × 2 methods; prune 4 tasks × 2 ratios; refs 2 scenes × 2 protocols
    # × 3 views; images 12 views × 4 sets, one view task each
    assert _units_of(est) == {"load": 2, "score": 4, "prune": 8, "render_ref": 12, "render+metrics": 48}
    assert est.stages["score"].detail == {"training_renders": 8, "camera_aware_tasks": 2}
    d = est.stages["render+metrics"].detail
    assert (d["view_tasks"], d["lpips_passes"], d["ssim_passes"], d["psnr_passes"]) == (12, 48, 48, 48)
    assert [(r["score_tasks"], r["sets"], r["images"]) for r in est.scenes] == [(2, 4, 24), (2, 4, 24)]


def test_mpeg_metrics_add_their_passes_and_identical_params_share_a_task(tmp_path):
    config, infos = _tiny(tmp_path, metrics=("3dgs", "mpeg"), extra_methods=[{"name": "opacity", "variant": "again"}])
    est = estimate(config, infos, None)
    # + YUV-SSIM, OM-YUV-SSIM, RGB/YUV-IVSSIM (each costed as an SSIM pass: an upper bound); RGB/YUV-PSNR (+OM)
    assert est.passes == {"lpips": 1, "ssim": 5, "psnr": 5}
    d = est.stages["render+metrics"].detail
    assert (d["lpips_passes"], d["ssim_passes"], d["psnr_passes"]) == (48, 240, 240)
    # opacity[again] has opacity's parameters: the same score task and the same pruned sets
    assert _units_of(est) == {"load": 2, "score": 4, "prune": 8, "render_ref": 12, "render+metrics": 48}


def _one_scene(size, splats=1000, views=4):
    return [SceneInfo("a", "read", "", [splats], [size] * views, [size] * 2)]


def test_render_cost_doubles_with_pixels_and_metrics_scale_with_them(tmp_path, monkeypatch):
    import harness.run.estimate as est_mod

    config, _ = _tiny(tmp_path)
    u = _units(render_px=1e-6, lpips_px=2e-6, ssim_px=1e-6, lpips_ref_px=1e-6)
    with_overhead = estimate(config, _one_scene((64, 48)), u).stages["render+metrics"]
    overhead = est_mod.IMAGE_OVERHEAD_S
    monkeypatch.setattr(est_mod, "IMAGE_OVERHEAD_S", 0.0)
    small = estimate(config, _one_scene((64, 48)), u)
    big = estimate(config, _one_scene((128, 48)), u)
    for stage in ("render_ref", "render+metrics"):
        assert big.stages[stage].core_s == pytest.approx(2 * small.stages[stage].core_s)
    # the fixed per-image overhead comes on top, once per image (16 = 4 views × 4 sets)
    assert with_overhead.core_s - small.stages["render+metrics"].core_s == pytest.approx(16 * overhead)
    # per-splat render work doubles with the splats instead
    u = _units(render_splat=1e-6)
    assert estimate(config, _one_scene((64, 48), 2000), u).stages["render_ref"].core_s == pytest.approx(
        2 * estimate(config, _one_scene((64, 48), 1000), u).stages["render_ref"].core_s)


def test_camera_aware_scoring_scales_with_views_and_splats(tmp_path):
    config, _ = _tiny(tmp_path)
    u = _units(render_splat=1e-6)
    one = estimate(config, [SceneInfo("a", "read", "", [1000], [(64, 48)], [(64, 48)] * 2)], u)
    more = estimate(config, [SceneInfo("a", "read", "", [2000], [(64, 48)], [(64, 48)] * 4)], u)
    assert more.stages["score"].core_s == pytest.approx(4 * one.stages["score"].core_s)
    assert one.stages["score"].longest_s == pytest.approx(2 * 1000 * 1e-6)  # 2 training renders, k = 1


def test_doubling_workers_halves_the_wall_time_down_to_the_longest_task():
    stages = {"load": Stage("load", 1, 10.0), "score": Stage("score", 10, 1000.0, 50.0),
              "prune": Stage("prune", 1, 5.0), "render_ref": Stage("render_ref"),
              "render+metrics": Stage("render+metrics", 10_000, 1e6, 200.0)}
    est = Estimate(stages, [], {})
    serial, startup = 15.0, POOL_START_S  # the pool starts once per run
    pool = [est.wall_s(w, 1.0) - serial - startup for w in (1, 2, 4)]
    assert pool[1] == pytest.approx(pool[0] / 2) and pool[2] == pytest.approx(pool[0] / 4)
    floor = serial + startup + 50.0 + 200.0  # each pool stage takes at least its longest task
    assert est.wall_s(100_000, 1.0) == pytest.approx(floor)
    assert est.wall_s(100_000, 1.0) == est.wall_s(200_000, 1.0)
    assert est.wall_s(8, 0.5) == pytest.approx(est.wall_s(4, 1.0))
    assert est.nodes(8.0, 16, 1.0)[0] == 3  # ceil(1,001,015 s / (8 h × 16 cores)) = ceil(2.17)


def test_one_worker_runs_in_process_and_the_reference_renders_pipeline_with_the_view_tasks():
    stages = {"load": Stage("load", 1, 1.0), "score": Stage("score"), "prune": Stage("prune", 1, 2.0),
              "render_ref": Stage("render_ref", 4, 40.0, 10.0),
              "render+metrics": Stage("render+metrics", 8, 60.0, 30.0)}
    est = Estimate(stages, [], {})
    walls = est.stage_walls(1, 0.5)  # one worker: no parallel loss, whatever the efficiency
    assert walls == {"load": 1.0, "prune": 2.0, "score": 0.0, "render_metrics": 100.0 + POOL_START_S}
    assert est.stage_walls(1000, 1.0)["render_metrics"] == 30.0 + POOL_START_S  # the longer longest task
    assert est.wall_s(2, 0.5) == pytest.approx(3.0 + 100.0 + POOL_START_S)


def test_absent_sequences_use_the_assumptions_and_say_so(tmp_path):
    doc = {"ratios": [0.3], "methods": ["opacity"], "protocol": {"metrics": ["3dgs"]},
           "scenes": [{"name": "breakfast_tracked", "sequence": str(tmp_path / "absent")},
                      {"name": "plant", "sequence": str(tmp_path / "gone"), "test_every": 4}]}
    config = parse_config(doc, "seq.yaml")
    infos = [scene_info(s, config, Assumptions()) for s in config.scenes]
    assert [i.status for i in infos] == ["assumed", "assumed"]
    assert "sequence folder not found" in infos[0].note and "assumed 32 frame(s)" in infos[0].note
    assert (len(infos[0].splats), infos[0].splats[0], len(infos[0].views), infos[0].views[0]) == (
        32, 1_000_000, 15, (1920, 1080))  # breakfast: 15 cameras, all measured
    assert (len(infos[1].views), len(infos[1].train)) == (6, 15)  # 21 cameras, every 4th held out
    mine = scene_info(config.scenes[1], config, Assumptions(frames=2, views=8, splats=500, size=(640, 480)))
    assert (mine.splats, len(mine.views), mine.views[0], len(mine.train)) == ([500, 500], 2, (640, 480), 6)


def test_missing_benchmark_files_fall_back_with_a_message(tmp_path):
    units = from_bench(tmp_path)
    assert units.lpips_px > 0 and units.render_px > 0 and "lightgs" in units.aware
    assert any("metrics.json is missing" in n for n in units.notes)
    here = from_bench(REPO / "results" / "bench")
    assert not any("missing" in n for n in here.notes)
    assert here.sources["lpips_px"].startswith("calibrate-cpu.json units.lpips_px")  # measured units win
    import shutil

    shutil.copy(REPO / "results" / "bench" / "metrics.json", tmp_path / "metrics.json")
    assert from_bench(tmp_path).sources["lpips_px"].startswith("metrics.json lpips_cached_per_pruned_s")


def test_ctc_estimate_runs_and_reports_every_sequence_as_assumed(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("MPEG_CTC_ROOT", str(tmp_path / "no-content"))
    out = tmp_path / "ctc.json"
    rc = main(["plan", str(REPO / "ctc_configs" / "ctc.yaml"), "--estimate", "--out", str(out)])
    text = capsys.readouterr().out
    assert rc == 0
    doc = json.loads(out.read_text())
    assert len(doc["assumed"]) == 23 and len(doc["scenes"]) == 23
    assert "23 scenes (0 read, 23 assumed)" in text and "Overnight" in text
    assert doc["cpu_hours"] > 0 and doc["overnight"]["nodes"] >= 1
    assert doc["wall_hours"]["2"] > doc["wall_hours"]["32"] > doc["wall_hours"]["128"]


def test_counts_only_without_estimate(tmp_path, capsys):
    config, _ = _tiny(tmp_path)
    (tmp_path / "tiny.yaml").write_text(json.dumps(config.raw))
    assert main(["plan", str(tmp_path / "tiny.yaml")]) == 0
    text = capsys.readouterr().out
    assert "| render+metrics | 48 images" in text and "CPU-hours" not in text


@pytest.mark.parametrize("args, phrase", [
    (["{cfg}"], "unknown key 'bogus'"),
    (["{missing}"], "no such file"),
    (["{good}", "--efficiency", "2"], "--efficiency: must be in (0, 1]"),
    (["{good}", "--assume-frames", "0"], "--assume-frames: must be at least 1"),
    (["{typo}"], "scenes[0] 'luigii': unknown scene name 'luigii' (did you mean 'luigi'?)"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, args, phrase):
    (tmp_path / "bad.yaml").write_text("bogus: 1\nscenes: [luigi]\nmethods: [opacity]\nratios: [0.1]\n")
    (tmp_path / "typo.yaml").write_text("scenes: [luigii]\nmethods: [opacity]\nratios: [0.1]\n")
    (tmp_path / "good.yaml").write_text("scenes: [luigi]\nmethods: [opacity]\nratios: [0.1]\n")
    paths = {"cfg": tmp_path / "bad.yaml", "missing": tmp_path / "nope.yaml", "good": tmp_path / "good.yaml",
             "typo": tmp_path / "typo.yaml"}
    rc = main(["plan", *(a.format(**paths) for a in args)])
    out, err = capsys.readouterr()
    assert rc == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and err.startswith("harness: ") and phrase in err, err
