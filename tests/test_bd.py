"""Rate points and BD metrics: known values (analytic shifts), an independent VCEG-M33 cubic
implementation written here, the table layouts, and the exact .ply size model against real writes."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from harness.io.cameras import ply_camera_comments
from harness.io.ply import write_ply
from harness.io.plysize import ply_size, ply_size_model
from harness.report.bd import (
    bd_pair,
    bd_rows,
    interpolation,
    rate_points,
    table_bd,
    table_ctc,
)
from tests.scene_factory import random_scene

# the classic example of the bjontegaard package's README (four rate points, kbps / dB)
R_A = [9487.76, 4593.60, 2486.44, 1358.24]
Q_A = [40.037, 38.615, 37.347, 36.125]
R_T = [9787.80, 4469.00, 2451.52, 1356.24]
Q_T = [40.121, 38.651, 37.308, 35.979]


def vceg_m33(r1, q1, r2, q2):
    """Bjøntegaard's VCEG-M33 procedure written out: cubic fits of log-rate(quality) / quality(log-rate),
    integrated over the common interval (BD-rate %, BD-PSNR dB)."""
    l1, l2 = np.log10(r1), np.log10(r2)
    lo, hi = max(min(q1), min(q2)), min(max(q1), max(q2))
    i1, i2 = np.polyint(np.polyfit(q1, l1, 3)), np.polyint(np.polyfit(q2, l2, 3))
    d = ((np.polyval(i2, hi) - np.polyval(i2, lo)) - (np.polyval(i1, hi) - np.polyval(i1, lo))) / (hi - lo)
    rate = (10 ** d - 1) * 100
    lo, hi = max(min(l1), min(l2)), min(max(l1), max(l2))
    j1, j2 = np.polyint(np.polyfit(l1, q1, 3)), np.polyint(np.polyfit(l2, q2, 3))
    dq = ((np.polyval(j2, hi) - np.polyval(j2, lo)) - (np.polyval(j1, hi) - np.polyval(j1, lo))) / (hi - lo)
    return rate, dq


def test_against_an_independent_vceg_m33_cubic():
    rate, dq, how = bd_pair(R_A, Q_A, R_T, Q_T)
    want_rate, want_dq = vceg_m33(*(np.array(x) for x in (R_A, Q_A, R_T, Q_T)))
    assert how == "cubic"
    assert rate == pytest.approx(want_rate, abs=1e-9) and dq == pytest.approx(want_dq, abs=1e-12)
    # the values two implementations agree on for this example: the test codec saves 1.19 % at equal
    # PSNR and gains 0.025 dB at equal rate (cubic); pchip gives −1.1707 % / 0.0227 dB
    assert round(rate, 4) == -1.1939 and round(dq, 4) == 0.0252


@pytest.mark.parametrize("n", [2, 3, 4, 5])
def test_known_values_from_exact_shifts(n):
    """Same curve with 10 % fewer bytes: BD-rate −10 % exactly; +0.5 dB at the same rates: BD-PSNR +0.5."""
    r = np.geomspace(1e5, 8e5, n)
    q = 30 + 4 * np.log10(r / 1e5) - 0.3 * np.log10(r / 1e5) ** 2
    rate, dq, how = bd_pair(r, q, 0.9 * r, q)
    assert how == ("cubic" if n >= 4 else "pchip") == interpolation(n, n)
    assert rate == pytest.approx(-10.0, abs=1e-9)
    rate2, dq2, _ = bd_pair(r, q, r, q + 0.5)
    assert dq2 == pytest.approx(0.5, abs=1e-9) and rate2 < 0


def test_ssim_bd_rate_on_the_db_scale():
    """SSIMs crowding below 1 (luigi, lightgs anchor vs opacity): the test curve is worse at every rate."""
    ra = [494298, 691839, 790643, 889379]
    qa, qt = [0.998036, 0.999805, 0.999963, 0.999996], [0.988115, 0.996123, 0.998436, 0.999603]
    rate, dq, _ = bd_pair(ra, qa, ra, qt, ssim=True)
    assert rate > 0 and dq < 0


def test_undefined_cases_are_nan():
    assert all(math.isnan(v) for v in bd_pair([1, 2, 3], [30, 29, 31], [1, 2, 3], [30, 31, 32])[:2])  # not monotone
    assert math.isnan(bd_pair([1], [30], [1, 2], [30, 31])[0])
    assert math.isnan(bd_pair([1, 2], [30, 31], [10, 20], [40, 41])[0])  # no quality overlap


def _summary():
    rows = []
    for scene, base in (("A", 100_000), ("B", 50_000)):
        for method, gain in (("lightgs", 0.0), ("betadesc", -2.0), ("opacity", -4.0)):
            for r in (0.1, 0.2, 0.3):
                n = int(base * (1 - r))
                q = 40 + gain - 60 * r
                rows.append({"scene": scene, "label": scene, "method": method, "variant": "default", "ratio": r,
                             "splats_out": n, "bytes": 300 + 248 * n, "rgb_psnr": q, "yuv_psnr": q + 3,
                             "yuv_ssim": 0.99 - r / 10 + gain / 1000, "score_s": 1.0, "psnr": q, "n": 2,
                             "rgb_psnr_std": 0.5})
    return pd.DataFrame(rows)


def test_rate_points_and_tables():
    s = _summary()
    d = rate_points(s)
    assert dict(zip(d[d["method"] == "lightgs"]["ratio"], d[d["method"] == "lightgs"]["rp"])) == \
        {0.3: "RP1", 0.2: "RP2", 0.1: "RP3"}
    assert set(d[d["ratio"] == 0.3]["level"]) == {"High"}
    long = bd_rows(s)
    assert set(long["method"]) == {"betadesc", "opacity"} and (long["interp"] == "pchip").all()
    assert (long[long["metric"] == "RGB-PSNR"]["bd_quality"] < 0).all()
    t = table_bd(s)
    num = t.tidy.set_index(["Sequence", "Method", "column_1", "column_2"])
    assert ("average", "BetaDescPrune", "RGB-PSNR", "BD-PSNR") in num.index
    avg = num.loc[("average", "BetaDescPrune", "RGB-PSNR", "BD-PSNR")]
    assert avg["value"] == pytest.approx(-2.0, abs=0.05) and np.isfinite(avg["std"])  # std over scenes beside it
    assert t.disp.loc[("average", "BetaDescPrune"), ("RGB-PSNR", "BD-PSNR")].startswith("-2.0")
    assert any("anchor: LightGSPrune" in n for n in t.notes) and t.caption.startswith("n = rate points")
    rate = table_bd(s, anchor="opacity").tidy.set_index(["Sequence", "Method", "column_1", "column_2"])["value"]
    assert rate[("A", "BetaDescPrune", "RGB-PSNR", "BD-rate (%)")] < 0
    ctc = table_ctc(s)
    assert list(ctc.disp.index.names) == ["Sequence", "Method", "RP"]
    assert {"splats", "bytes", "RGB-PSNR", "YUV-PSNR", "YUV-SSIM", "seconds"} <= set(ctc.disp.columns)
    psnr = ctc.tidy[ctc.tidy["column"] == "RGB-PSNR"]
    assert (psnr["std"] == 0.5).all() and ctc.tidy.loc[ctc.tidy["column"] == "splats", "std"].isna().all()


def test_ply_size_model_equals_real_writes(tmp_path):
    from harness.core.cameras import Camera

    cams = [Camera.look_at((0, 0, -3), (0, 0, 0), width=64, height=48, name="a")]
    for i, (n, sh, extra) in enumerate([(0, 0, False), (9, 1, True), (1234, 3, False), (99999, 0, True)]):
        scene = random_scene(n, sh, seed=i, extra=extra).with_meta(preamble=tuple(ply_camera_comments(cams)),
                                                                     comments=("hello",))
        model = ply_size_model(scene)
        for k in sorted({0, n // 3, n}):
            sub = scene.subset(np.arange(k))
            write_ply(sub, tmp_path / "x.ply")
            assert (tmp_path / "x.ply").stat().st_size == model(k) == ply_size(sub)
