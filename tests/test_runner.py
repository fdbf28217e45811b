"""Runner: stages, caching, dedup, skips and failures — in-process with fast fakes (tests/runner_fakes.py)."""

from __future__ import annotations

import numpy as np
import pytest

from harness.io.scenes import write_scene
from harness.report.results import to_frame
from harness.run.config import parse_config
from harness.run.runner import Runner
from tests import runner_fakes as fakes
from tests.scene_factory import random_scene


@pytest.fixture
def scenes(tmp_path):
    return fakes.write_two_scenes(tmp_path)


def _config(scenes, methods, **extra):
    """``scenes``: {name: path} or a list of scene entries."""
    doc = {
        "name": "t",
        "protocol": {"longest_side": 32, "metrics": ["psnr", "ssim"], "n_train": 3, "n_test": 2},
        "ratios": [0.1, 0.3],
        "scenes": [{"name": k, "source": v} for k, v in scenes.items()] if isinstance(scenes, dict) else scenes,
        "methods": methods,
        **extra,
    }
    return parse_config(doc, "test.yaml")


def _run(cfg, tmp_path, **kw):
    r = Runner(cfg, out_dir=tmp_path / "out", cache_root=tmp_path / "cache", toolkit=fakes.toolkit(),
               log=lambda m: None, **kw)
    res = r.run()
    return res, to_frame(res.rows)


def _metric_cols(df):
    return df[["scene", "method", "variant", "ratio", "view", "status", "psnr", "ssim", "splats_out", "tau"]]


def test_rows_and_rerun_recomputes_nothing(scenes, tmp_path):
    cfg = _config(scenes, ["fake-norm", "opacity"])
    fakes.CALLS.clear()
    res, df = _run(cfg, tmp_path)
    # 2 scenes x 2 methods x 2 ratios x 2 views
    assert len(df) == 16 and (df["status"] == "ok").all()
    assert fakes.CALLS["score:fake-norm"] == 2  # once per scene, reused by both ratios
    assert sum(c["misses"] for c in res.counts.values()) > 0
    ok = df.iloc[0]
    assert ok["splats_in"] == 300 and ok["splats_out"] == 300 - round(ok["ratio"] * 300)

    fakes.CALLS.clear()
    res2, df2 = _run(cfg, tmp_path)
    assert sum(c["misses"] for c in res2.counts.values()) == 0
    assert fakes.CALLS["render"] == 0 and fakes.CALLS["score:fake-norm"] == 0
    assert _metric_cols(df2).equals(_metric_cols(df))


def test_identical_keep_masks_are_rendered_once(scenes, tmp_path):
    # fake-norm's `unused` parameter changes the cache key but not the scores: same masks
    cfg = _config({"s0": scenes["s0"]}, [{"name": "fake-norm", "sweep": {"unused": [0, 1, 2]}}])
    fakes.CALLS.clear()
    res, df = _run(cfg, tmp_path)
    assert fakes.CALLS["score:fake-norm"] == 3
    # per view: 1 reference + 2 distinct masks (ratios 0.1, 0.3), although 3 variants x 2 ratios use them
    assert fakes.CALLS["render"] == 2 * (1 + 2)
    assert res.counts["metrics"]["misses"] == 2 * 2
    assert sorted(set(df["variant"])) == ["unused=0", "unused=1", "unused=2"]
    per_variant = df.pivot_table(index=["ratio", "view"], columns="variant", values="psnr")
    assert np.allclose(per_variant.to_numpy(), per_variant.to_numpy()[:, :1])


def test_changing_params_recomputes_only_that_method(scenes, tmp_path):
    _run(_config(scenes, ["opacity", {"name": "fake-norm", "params": {"unused": 1}}]), tmp_path)
    fakes.CALLS.clear()
    res, _ = _run(_config(scenes, ["opacity", {"name": "fake-norm", "params": {"unused": 2}}]), tmp_path)
    assert fakes.CALLS["score:fake-norm"] == 2  # one per scene; opacity's scores are reused
    assert res.counts["score"] == {"hits": 2, "misses": 2}
    assert res.counts["render_ref"]["misses"] == 0  # reference renders are shared by every method


def test_camera_aware_without_cameras_is_skipped_with_reason(scenes, tmp_path):
    cfg = _config({"s0": scenes["s0"]}, ["fake-aware", "opacity"], protocol={
        "longest_side": 32, "metrics": ["psnr"], "n_train": 0, "n_test": 1})
    _, df = _run(cfg, tmp_path)
    skipped = df[df["method"] == "fake-aware"]
    assert len(skipped) == 1 and skipped.iloc[0]["status"] == "skipped"
    assert "fake-aware needs cameras" in skipped.iloc[0]["reason"]
    assert (df[df["method"] == "opacity"]["status"] == "ok").all()


def test_camera_aware_gets_train_views(scenes, tmp_path):
    fakes.CALLS.clear()
    _, df = _run(_config({"s0": scenes["s0"]}, ["fake-aware"]), tmp_path)
    assert fakes.CALLS["score:fake-aware"] == 1 and (df["status"] == "ok").all()


def test_missing_scene_and_broken_pruner_do_not_stop_the_run(scenes, tmp_path):
    cfg = _config(
        [
            {"name": "s0", "source": scenes["s0"]},
            {"name": "gone", "source": str(tmp_path / "nope.ply"), "optional": True},
        ],
        ["fake-broken", "opacity"],
    )
    res, df = _run(cfg, tmp_path)
    gone = df[df["scene"] == "gone"]
    assert len(gone) == 1 and gone.iloc[0]["status"] == "skipped" and "not found" in gone.iloc[0]["reason"]
    broken = df[df["method"] == "fake-broken"]
    assert (broken["status"] == "error").all() and "broken on purpose" in broken.iloc[0]["reason"]
    assert res.errors and (df[df["method"] == "opacity"]["status"] == "ok").all()


def test_force_recomputes(scenes, tmp_path):
    cfg = _config({"s0": scenes["s0"]}, ["fake-norm"])
    _, df = _run(cfg, tmp_path)
    fakes.CALLS.clear()
    res, df2 = _run(cfg, tmp_path, force=True)
    assert fakes.CALLS["score:fake-norm"] == 1 and fakes.CALLS["render"] == 2 * 3
    assert sum(c["hits"] for c in res.counts.values()) == 0
    assert _metric_cols(df2).equals(_metric_cols(df))


@pytest.mark.slow  # spawning two workers (torch imports) takes ~25 s here
def test_pool_of_two_workers_matches_in_process(scenes, tmp_path):
    cfg = _config(scenes, ["fake-norm", "opacity"])
    _, df1 = _run(cfg, tmp_path / "a")
    _, df2 = _run(cfg, tmp_path / "b", workers=2)
    assert _metric_cols(df2).equals(_metric_cols(df1))


def test_frames_sequence_shares_views_and_aggregates(tmp_path):
    seq = tmp_path / "seq"
    seq.mkdir()
    for f in range(3):
        write_scene(random_scene(200, seed=10 + f), seq / f"frame_{f:03d}.ply")
    cfg = _config([{"name": "seq", "frames": str(seq / "frame_*.ply"), "kind": "forward-facing"}], ["fake-norm"])
    fakes.CALLS.clear()
    res, df = _run(cfg, tmp_path)
    assert sorted(set(df["frame"])) == ["frame_000", "frame_001", "frame_002"]
    assert fakes.CALLS["score:fake-norm"] == 3  # one score per frame
    assert res.counts["views"]["misses"] == 1  # the first frame's views serve the sequence
    assert len(df) == 3 * 2 * 2 and set(df.groupby("frame")["view"].apply(frozenset)) == {frozenset(df["view"])}


def test_cameras_file_split_by_name(tmp_path, scenes):
    from harness.io.cameras import write_3dgs_cameras

    _, train, test = fakes.make_rig("x", None, kind="", dataset=None, n_train=3, n_test=2, longest_side=64,
                                    aspect=1.0, seed=0)
    cams = train + test
    write_3dgs_cameras(cams, tmp_path / "cams.json")
    names = [c.name for c in test]
    cfg = _config([{"name": "s0", "source": scenes["s0"],
                    "cameras": {"path": str(tmp_path / "cams.json"), "test": names}}], ["fake-aware"])
    _, df = _run(cfg, tmp_path)
    assert sorted(set(df["view"])) == sorted(names) and (df["status"] == "ok").all()
    assert set(df["width"]) == {32}  # resized to the protocol's longest side
    missing = _config([{"name": "s0", "source": scenes["s0"], "optional": True,
                        "cameras": {"path": str(tmp_path / "gone.json"), "test_every": 8}}], ["opacity"])
    _, df2 = _run(missing, tmp_path)
    assert df2.iloc[0]["status"] == "skipped" and "cameras not found" in df2.iloc[0]["reason"]


def test_an_absent_required_scene_is_an_error_before_any_work(scenes, tmp_path):
    """Issue 23: `name: luigii` was skipped (exit 0) and the run replaced the previous tables. A scene
    not marked optional must resolve before any work; the Runner records one that vanished as an error."""
    from harness.core.errors import InputError
    from harness.run.sources import check_sources

    cfg = _config([{"name": "s0", "source": scenes["s0"]}, {"name": "luigii"},
                   {"name": "cams", "source": scenes["s1"], "cameras": {"path": "gone.json", "test_every": 8}},
                   {"name": "mpeg", "sequence": str(tmp_path / "absent"), "optional": True}], ["opacity"])
    with pytest.raises(InputError) as err:
        check_sources(cfg, fakes.toolkit(), tmp_path)
    msg = str(err.value)
    assert msg.startswith("test.yaml: scenes[1] 'luigii': unknown scene name 'luigii' (did you mean 'luigi'?)")
    assert "scenes[2] 'cams': cameras not found: gone.json" in msg and "'mpeg'" not in msg and "\n" not in msg
    assert "optional: true" in msg
    _, df = _run(cfg, tmp_path)  # the Runner alone (no check): required ones error, the optional one skips
    status = df.drop_duplicates("scene").set_index("scene")["status"]
    assert status["luigii"] == "error" and status["cams"] == "error" and status["mpeg"] == "skipped"
    assert status["s0"] == "ok"


def test_missing_lpips_weights_fail_before_any_work(scenes, tmp_path, monkeypatch):
    from harness.core.errors import InputError

    monkeypatch.setenv("HARNESS_CACHE", str(tmp_path / "empty-home"))
    cfg = _config({"s0": scenes["s0"]}, ["opacity"], protocol={"longest_side": 32, "metrics": ["lpips"]})
    with pytest.raises(InputError, match="harness fetch --weights"):
        _run(cfg, tmp_path)
    assert not (tmp_path / "cache" / "score").exists()


def test_pruner_version_follows_imported_project_modules():
    from harness.run.cache.versions import project_closure

    mods = project_closure("tests.runner_fakes", roots=("tests", "harness", "methods"))
    assert {
        "tests.runner_fakes",
        "harness.core.cameras",
        "harness.core.scene",
        "methods.registry",
        "harness.run.toolkit",
    } <= mods
    assert not any(m.startswith(("numpy", "renderers")) for m in mods)
    # imports inside functions count: betadesc's pipeline is imported when a variant runs
    full = project_closure("methods.betadesc")
    assert {"methods.betadesc.pipeline", "methods.betadesc.fpfh", "methods.betadesc.statistics"} <= full
    assert "renderers.projection" in project_closure("methods.lightgs")


def test_bad_scene_file_or_split_is_an_error_row_and_the_run_goes_on(scenes, tmp_path):
    from harness.io.cameras import write_3dgs_cameras

    bad = tmp_path / "bad.ply"
    bad.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 10\nend_header\n")
    _, train, test = fakes.make_rig("x", None, kind="", dataset=None, n_train=2, n_test=1, longest_side=64,
                                    aspect=1.0, seed=0)
    write_3dgs_cameras(train + test, tmp_path / "cams.json")
    cfg = _config([{"name": "bad", "source": str(bad)}, {"name": "s0", "source": scenes["s0"]},
                   {"name": "split", "source": scenes["s1"],
                    "cameras": {"path": str(tmp_path / "cams.json"), "test": ["v99"]}}], ["opacity"])
    res, df = _run(cfg, tmp_path)
    rows = df.set_index("scene")
    assert rows.loc["bad", "status"] == "error" and "cannot use it" in rows.loc["bad", "reason"]
    assert rows.loc["split", "status"] == "error" and "v99" in rows.loc["split", "reason"]
    assert (df[df["scene"] == "s0"]["status"] == "ok").all() and len(res.errors) == 2


def test_betadesc_gets_training_views_only_when_its_view_evidence_is_on(scenes, tmp_path):
    """view_weight > 0: the runner hands betadesc the rig's training views (the paper's optional
    view-aware edge evidence); at 0 (the default) it stays camera-agnostic and its scores do not
    depend on the cameras."""
    small = {"voxel": 0.05, "radius_voxels": 3.0, "max_nn": 40}
    methods = [{"name": "betadesc", "variant": "agnostic", "params": small},
               {"name": "betadesc", "variant": "views", "params": {**small, "view_weight": 1.0}}]
    one = {"s0": scenes["s0"]}
    _, df = _run(_config(one, methods), tmp_path)
    assert (df["status"] == "ok").all()
    psnr = df.pivot_table(index=["ratio", "view"], columns="variant", values="psnr")
    assert not np.allclose(psnr["agnostic"], psnr["views"])  # the edge evidence changed what is pruned
    # other training views: only the view-aware variant is scored again
    res, _ = _run(_config(one, methods, protocol={"longest_side": 32, "metrics": ["psnr"], "n_train": 5,
                                                  "n_test": 2}), tmp_path)
    assert res.counts["score"] == {"hits": 1, "misses": 1}


@pytest.mark.parametrize("workers", [1, 2])
def test_progress_lines_count_what_was_done(scenes, tmp_path, workers):
    """The plain (non-terminal) progress lines end with done N/N per stage; they used to print
    'render_ref: done 0/4' after rendering the four references in-process."""
    import io

    from rich.console import Console

    from harness.run.progress import StageProgress

    buf = io.StringIO()
    console = Console(file=buf, force_terminal=False, width=200)
    with StageProgress(console) as progress:
        _run(_config(scenes, ["opacity"]), tmp_path, progress=progress, workers=workers)
    done = [line for line in buf.getvalue().splitlines() if ": done " in line]
    assert done and all(
        line.split("done ")[1].split()[0].split("/")[0] == line.split("done ")[1].split()[0].split("/")[1]
        for line in done
    ), done
    assert any(line.strip().startswith("render_ref: done 4/4") for line in done)


def test_shifted_view_protocol(scenes, tmp_path):
    """protocols: [rig, shifted] — the same scores and masks measured on the rig's held-out views and
    on views from another camera distribution; rows name their protocol; tables come per protocol."""
    from harness.report.outputs import publish
    from harness.report.tracking import summarize_groups

    cfg = _config({"s0": scenes["s0"]}, ["opacity", "random"], protocols=["rig", "shifted"])
    res, df = _run(cfg, tmp_path)
    assert (df["status"] == "ok").all() and set(df["protocol"]) == {"rig", "shifted"}
    rig = df[df["protocol"] == "rig"]
    shifted = df[df["protocol"] == "shifted"]
    assert len(rig) == len(shifted) == 2 * 2 * 2  # methods x ratios x 2 held-out views
    assert all(v.startswith("shifted/") for v in shifted["view"]) and not any("/" in v for v in rig["view"])
    assert res.counts["score"]["misses"] == 2  # scored once for both protocols
    written = publish(tmp_path / "out", df, {}, tables=["comparison", "versus"], plots=[]).written
    names = {p.name for p in written.paths}
    assert {"comparison.md", "comparison-shifted.md", "versus-shifted.csv"} <= names
    assert "held-out views: shifted" in (tmp_path / "out" / "tables" / "comparison-shifted.md").read_text()
    keys = summarize_groups(df)
    assert any(k.startswith("s0@shifted|") for k in keys) and any(k.startswith("s0|") for k in keys)


def test_protocol_config_errors():
    from harness.core.errors import InputError

    base = {"scenes": ["a"], "methods": ["opacity"], "ratios": [0.1]}
    for protocols, msg in (
        (["shifted"], "first protocol must be the training rig"),
        (["rig", "tilted"], "unknown view protocol .tilted."),
        ([], "non-empty list"),
        (["rig", {"name": "x", "fov_scale": 9}], "fov_scale"),
    ):
        with pytest.raises(InputError, match=msg):
            parse_config({**base, "protocols": protocols}, "c.yaml")
    cfg = parse_config({**base, "protocols": ["rig", {"name": "steep", "rings_above": [40]}]}, "c.yaml")
    assert [p.name for p in cfg.protocols] == ["rig", "steep"] and cfg.protocols[1].params.rings_above == (40.0,)
    assert cfg.protocols[1].spec.name == "shifted" and cfg.protocols[1].params.fov_scale == 1.0  # only what it names
