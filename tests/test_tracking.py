"""`harness track`: summaries of small hand-made tidy results, comparison rules, the CLI's exit codes."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from harness.cli import main
from harness.report import tracking
from harness.report.results import to_frame, write_results

CALIB = 0.5


def _rows(psnr=(30.0, 32.0), ssim=(0.95, 0.97), lpips=(0.05, 0.07), score_s=4.0, render_s=2.0,
          method="betadesc", status="ok"):
    """Two views of one (scene, method, ratio) group plus an opacity group, as the runner writes them."""
    rows = []
    for m, ps, ss, lp in ((method, psnr, ssim, lpips), ("opacity", (25.0, 27.0), (0.9, 0.92), (0.1, 0.12))):
        for v, (p, s, lpv) in enumerate(zip(ps, ss, lp)):
            rows.append(
                {
                    "run": "t",
                    "scene": "grape",
                    "label": "grape",
                    "kind": "object-centric",
                    "frame": "",
                    "method": m,
                    "variant": "default",
                    "params": "{}",
                    "ratio": 0.3,
                    "keep": 0.7,
                    "view": f"view{v:02d}",
                    "status": status if m == method else "ok",
                    "reason": "",
                    "psnr": p,
                    "ssim": s,
                    "lpips": lpv,
                    "splats_in": 100,
                    "splats_out": 70,
                    "score_s": score_s if m == method else 4.0,
                    "prune_s": 0.01,
                    "render_ref_s": 1.0,
                    "render_s": render_s,
                    "metrics_s": 0.5,
                    "renderer": "gl",
                    "width": 64,
                    "height": 48,
                }
            )
    return rows


def _meta(total=20.0, calib=CALIB, hits=0):
    return {"name": "t", "commit": "abc123", "machine": {"cpus": 2}, "calibration_s": calib,
            "stage_seconds": {"load": 1.0, "score": 8.0, "render_metrics": 10.0, "total": total},
            "cache_counts": {"score": {"hits": hits, "misses": 2}}}


def _summary(rows=None, meta=None):
    return tracking.build_summary(to_frame(rows if rows is not None else _rows()), meta or _meta())


def _baseline(**tol):
    return {"tolerances": {**tracking.DEFAULT_TOLERANCES, **tol}, "summary": _summary()}


def _regressions(findings):
    return [f for f in findings if f.kind == "regression"]


def test_summary_means_per_group_and_stage_keys():
    s = _summary()
    g = s["groups"]["grape|betadesc[default]|0.3"]
    assert g["n_views"] == 2 and g["psnr"] == pytest.approx(31.0) and g["psnr_n_inf"] == 0
    assert g["ssim"] == pytest.approx(0.96) and g["lpips"] == pytest.approx(0.06)
    assert s["stages"]["score:grape|betadesc[default]"] == 4.0
    assert s["stages"]["render:grape"] == 2.0 and s["stages"]["run:total"] == 20.0
    assert s["commit"] == "abc123" and s["calibration_source"] == "run.json"


def test_inf_psnr_excluded_from_mean_and_counted():
    s = _summary(_rows(psnr=(math.inf, 30.0)))
    g = s["groups"]["grape|betadesc[default]|0.3"]
    assert g["psnr"] == pytest.approx(30.0) and g["psnr_n_inf"] == 1
    all_inf = _summary(_rows(psnr=(math.inf, math.inf)))["groups"]["grape|betadesc[default]|0.3"]
    assert all_inf["psnr"] is None and all_inf["psnr_n_inf"] == 2
    json.dumps(s, allow_nan=False)  # a summary with inf PSNR is still strict JSON


def test_identical_summaries_pass():
    findings = tracking.compare(_baseline(), _summary())
    assert not _regressions(findings)
    assert sum(f.kind == "ok" for f in findings) >= 6  # 3 metrics x 2 groups, plus stages


@pytest.mark.parametrize("change, what", [
    ({"psnr": (29.0, 31.0)}, "PSNR"),          # -1 dB on the mean
    ({"ssim": (0.94, 0.96)}, "SSIM"),          # -0.01
    ({"lpips": (0.06, 0.08)}, "LPIPS"),        # +0.01
])
def test_worse_metric_fails(change, what):
    bad = _regressions(tracking.compare(_baseline(), _summary(_rows(**change))))
    assert len(bad) == 1 and what in bad[0].message and bad[0].key == "grape|betadesc[default]|0.3"


def test_change_within_tolerance_passes_and_improvement_passes():
    assert not _regressions(tracking.compare(_baseline(), _summary(_rows(psnr=(29.7, 31.7)))))
    assert not _regressions(tracking.compare(_baseline(), _summary(_rows(psnr=(35.0, 36.0), lpips=(0.0, 0.0)))))


def test_slower_normalised_stage_fails_but_slower_machine_does_not():
    # twice as slow on the same machine (same calibration): the scoring stage regresses
    slow = _summary(_rows(score_s=8.0))
    bad = _regressions(tracking.compare(_baseline(), slow))
    assert [f.key for f in bad] == ["score:grape|betadesc[default]"]
    # everything (stages and calibration) twice as slow: a slower machine, not a regression
    rows = _rows(score_s=8.0, render_s=4.0)
    for r in rows:
        r["metrics_s"] *= 2
    meta = _meta(calib=2 * CALIB)
    meta["stage_seconds"] = {k: 2 * v for k, v in meta["stage_seconds"].items()}
    assert not _regressions(tracking.compare(_baseline(), _summary(rows, meta)))


def test_tiny_stages_are_not_compared():
    base = _baseline(min_stage_s=5.0)
    slow = _summary(_rows(score_s=4.9))  # 4.0 -> 4.9 s is +22 %, but also under the floor anyway
    assert not _regressions(tracking.compare(base, _summary(_rows(score_s=4.0 * 1.2))))
    assert not any(f.key.startswith("score:") and f.kind == "regression" for f in tracking.compare(base, slow))


def test_cached_run_stages_skipped():
    s = _summary(meta=_meta(hits=3))
    assert not any(k.startswith("run:") for k in s["stages"])


def test_missing_group_and_all_inf_baseline_regress():
    rows = [r for r in _rows() if r["method"] != "betadesc"]
    bad = _regressions(tracking.compare(_baseline(), _summary(rows)))
    assert any("no measured view" in f.message for f in bad)
    base = {"tolerances": dict(tracking.DEFAULT_TOLERANCES), "summary": _summary(_rows(psnr=(math.inf, math.inf)))}
    bad = _regressions(tracking.compare(base, _summary()))
    assert any("+inf on every view" in f.message for f in bad)


def test_errored_group_is_listed_without_views():
    s = _summary(_rows(status="error", psnr=(np.nan, np.nan), ssim=(np.nan, np.nan), lpips=(np.nan, np.nan)))
    assert s["groups"]["grape|betadesc[default]|0.3"]["n_views"] == 0


def test_calibration_workload_is_timed_when_run_json_lacks_it():
    meta = _meta()
    del meta["calibration_s"]
    s = _summary(meta=meta)
    assert s["calibration_source"] == "track" and 0 < s["calibration_s"] < 60


# --------------------------------------------------------------------------- CLI
def _run_dir(tmp_path, name, rows, meta):
    d = tmp_path / name
    d.mkdir()
    write_results(to_frame(rows), d)
    (d / "run.json").write_text(json.dumps(meta))
    return d


def test_cli_baseline_missing_then_update_then_pass_then_fail(tmp_path, capsys):
    good = _run_dir(tmp_path, "good", _rows(), _meta())
    worse = _run_dir(tmp_path, "worse", _rows(psnr=(25.0, 26.0)), _meta())
    base, hist = tmp_path / "hist" / "baseline.json", tmp_path / "hist"
    args = ["--baseline", str(base), "--history", str(hist)]

    assert main(["track", str(good), *args]) == 2  # no baseline, no --update-baseline: nothing written
    assert not base.exists() and "--update-baseline" in capsys.readouterr().err

    assert main(["track", str(good), *args, "--update-baseline"]) == 0
    saved = json.loads(base.read_text())
    assert saved["tolerances"]["psnr"] == 0.5 and "grape|betadesc[default]|0.3" in saved["summary"]["groups"]

    capsys.readouterr()
    assert main(["track", str(good), *args]) == 0
    assert "0 regressions" in capsys.readouterr().out

    assert main(["track", str(worse), *args]) == 1
    out = capsys.readouterr().out
    assert "REGRESSION" in out and "PSNR 31.000 -> 25.500" in out
    lines = (hist / "history.jsonl").read_text().splitlines()
    assert len(lines) == 3 and json.loads(lines[-1])["groups"]["grape|betadesc[default]|0.3"]["psnr"] == 25.5


def test_cli_keeps_tolerances_on_update_and_rejects_bad_baseline(tmp_path, capsys):
    good = _run_dir(tmp_path, "good", _rows(), _meta())
    base = tmp_path / "baseline.json"
    tracking.write_baseline(base, _summary(), {"psnr": 2.0})
    assert main(["track", str(good), "--baseline", str(base), "--no-history", "--update-baseline"]) == 0
    assert json.loads(base.read_text())["tolerances"]["psnr"] == 2.0
    base.write_text("{not json")
    assert main(["track", str(good), "--baseline", str(base), "--no-history"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not valid JSON" in err
    assert main(["track", str(tmp_path / "nowhere"), "--baseline", str(base)]) == 2


def test_summary_has_std_beside_every_mean_and_names_config_and_protocols():
    g = _summary()["groups"]["grape|betadesc[default]|0.3"]
    assert g["psnr"] == 31.0 and g["psnr_std"] == pytest.approx(math.sqrt(2.0))  # 30, 32: ddof = 1
    assert g["ssim_std"] == pytest.approx(np.std([0.95, 0.97], ddof=1))
    assert g["lpips_std"] == pytest.approx(np.std([0.05, 0.07], ddof=1))
    s = _summary()
    assert s["run"] == "t" and s["protocols"] == []  # these rows carry no protocol
    rows = [{**r, "protocol": "rig"} for r in _rows()] + [{**r, "protocol": "shifted"} for r in _rows()]
    assert _summary(rows)["protocols"] == ["rig", "shifted"]
    assert tracking.protocols_of({"groups": {"a@shifted|m[d]|0.1": {}, "a|m[d]|0.1": {}}}) == ["rig", "shifted"]


def _protocol_rows(*protocols):
    return [{**r, "protocol": p} for p in protocols for r in _rows()]


@pytest.mark.parametrize("name, protocols, phrase", [
    ("other", ("rig",), "config 'other'"),
    ("t", ("rig", "shifted"), "protocols rig, shifted"),
])
def test_cli_compares_only_like_with_like_and_writes_nothing_first(tmp_path, capsys, name, protocols, phrase):
    """Issue 23: a ci run tracked against the nightly baseline gave 74 false regressions, exit 1, and
    appended to the tracked history; with a bad baseline it appended, then exited 2."""
    base, hist = tmp_path / "baseline.json", tmp_path / "hist"
    tracking.write_baseline(base, _summary(_protocol_rows("rig")))
    before = base.read_bytes()
    run = _run_dir(tmp_path, "run", _protocol_rows(*protocols), {**_meta(), "name": name})
    assert main(["track", str(run), "--baseline", str(base), "--history", str(hist), "--update-baseline"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and phrase in err and "same config and protocols" in err
    assert base.read_bytes() == before and not hist.exists()
    (tmp_path / "bad.json").write_text("{not json")
    assert main(["track", str(run), "--baseline", str(tmp_path / "bad.json"), "--history", str(hist)]) == 2
    assert not hist.exists()  # decided before writing


def test_cli_appends_to_a_history_only_when_asked(tmp_path, capsys):
    good = _run_dir(tmp_path, "good", _rows(), _meta())
    base = tmp_path / "baseline.json"
    tracking.write_baseline(base, _summary())
    assert main(["track", str(good), "--baseline", str(base)]) == 0
    assert "history: not written" in capsys.readouterr().out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["baseline.json", "good"]
    assert main(["track", str(good), "--baseline", str(base), "--history", str(tmp_path / "h")]) == 0
    assert len((tmp_path / "h" / "history.jsonl").read_text().splitlines()) == 1


@pytest.mark.parametrize("kind", ["fifo", "symlink"])
def test_history_must_be_a_regular_file(tmp_path, capsys, kind):
    import os

    good = _run_dir(tmp_path, "good", _rows(), _meta())
    base = tmp_path / "baseline.json"
    tracking.write_baseline(base, _summary())
    hist = tmp_path / "h"
    hist.mkdir()
    other = tmp_path / "other.txt"
    other.write_text("someone else's file\n")
    if kind == "fifo":
        os.mkfifo(hist / "history.jsonl")
    else:
        (hist / "history.jsonl").symlink_to(other)
    assert main(["track", str(good), "--baseline", str(base), "--history", str(hist)]) == 2
    assert "regular file" in capsys.readouterr().err
    assert other.read_text() == "someone else's file\n"


def test_track_is_quiet_when_nothing_is_wrong_and_lists_every_check_with_v(tmp_path, capsys):
    """155 `ok` lines for a nightly run with nothing wrong: now a count, and every check with -v."""
    good = _run_dir(tmp_path, "good", _rows(), _meta())
    worse = _run_dir(tmp_path, "worse", _rows(psnr=(25.0, 26.0)), _meta())
    base = tmp_path / "baseline.json"
    assert main(["track", str(good), "--baseline", str(base), "--update-baseline"]) == 0
    capsys.readouterr()
    assert main(["track", str(good), "--baseline", str(base)]) == 0
    quiet = capsys.readouterr().out.splitlines()
    assert not [ln for ln in quiet if ln.startswith("ok ")]
    summary = next(ln for ln in quiet if ln.startswith("track: "))
    checks = int(summary.split()[1])
    assert checks >= 6 and summary.endswith(f"0 regressions, {checks} ok (-v lists them)")
    assert main(["track", str(good), "--baseline", str(base), "-v"]) == 0
    loud = capsys.readouterr().out.splitlines()
    assert len([ln for ln in loud if ln.startswith("ok ")]) == checks
    assert main(["track", str(worse), "--baseline", str(base)]) == 1
    out = capsys.readouterr().out.splitlines()
    assert [ln for ln in out if ln.startswith("REGRESSION")] and not [ln for ln in out if ln.startswith("ok ")]
