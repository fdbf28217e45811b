"""The virtual rig's goals table against hand-computed verdicts on made-up per-view results."""

from __future__ import annotations

import numpy as np
import pandas as pd

from harness.report.tabledata import Missing, Table
from harness.study.vrgoals import table_virtual_rig


def _results(protocol: str, gaps: dict[str, tuple[float, float]], noise: float = 0.05) -> pd.DataFrame:
    """Per scene: virtual-rig = lightgs + gap_lightgs, = opacity + gap_opacity, 8 views each."""
    rng = np.random.default_rng(0)
    rows = []
    for scene, (g_l, g_o) in gaps.items():
        base = 40.0 + rng.normal(size=8)
        jitter = noise * np.array([1, -1, 1, -1, 1, -1, 1, -1.0])
        sides = (("virtual-rig", base), ("lightgs", base - g_l + jitter), ("opacity", base - g_o - jitter))
        for method, values in sides:
            for k, v in enumerate(values):
                rows.append({"status": "ok", "scene": scene, "label": scene, "method": method, "variant": "default",
                             "ratio": 0.3, "view": f"v{k}", "psnr": v, "protocol": protocol, "params": "{}"})
    return pd.DataFrame(rows)


def _verdicts(t: Table) -> dict:
    return {s: (r["verdict"], r["above opacity"]) for s, r in t.disp.iterrows()}


def test_within_half_a_db_under_shifted():
    t = table_virtual_rig(_results("shifted", {"luigi": (-0.3, 2.0), "playbot": (-2.0, -1.0)}))
    assert _verdicts(t) == {"luigi": ("met (CI)", "met (CI)"), "playbot": ("not met (CI)", "not met (CI)")}
    assert t.disp.loc["luigi", "goal"] == "≥ −0.5 dB"
    assert t.disp.loc["luigi", "Δ vs LightGS [CI]"].startswith("-0.30")  # virtual-rig − LightGS


def test_rooms_must_beat_lightgs_under_independent_and_real():
    df = _results("independent", {"bonsai-7k": (-0.2, 1.0), "synth-room": (0.4, 1.0), "luigi": (-0.2, 1.0)})
    v = _verdicts(table_virtual_rig(df))
    assert v["bonsai-7k"][0] == "met (CI); not met (CI)"  # within 0.5 dB, but a room must be above LightGS
    assert v["synth-room"][0] == "met (CI); met (CI)"
    assert v["luigi"][0] == "met (CI)"  # not a room: only the 0.5 dB goal
    real = table_virtual_rig(_results("real", {"bonsai-7k": (0.5, 1.0)}))
    assert real.disp.loc["bonsai-7k", "goal"] == "> 0 (room)"
    rig = table_virtual_rig(_results("rig", {"luigi": (-3.0, 1.0)}))
    assert rig.disp.loc["luigi", "verdict"] == "–" and rig.disp.loc["luigi", "above opacity"] == "met (CI)"


def test_a_verdict_the_interval_does_not_back_says_so():
    t = table_virtual_rig(_results("shifted", {"luigi": (-0.45, 1.0)}, noise=1.0))
    assert t.disp.loc["luigi", "verdict"] == "met"  # the mean is within 0.5 dB; the interval reaches below


def test_missing_methods_are_one_line():
    df = _results("shifted", {"luigi": (0.0, 1.0)})
    assert isinstance(table_virtual_rig(df[df["method"] != "lightgs"]), Missing)
