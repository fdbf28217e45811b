"""The pre-registered selection engine as the virtual rig's rule uses it (``ctc_configs/study/virtualrig.yaml``):
reference lightgs, two protocols pooled, an over-budget value ruled out, and an axis that does not
apply to a scene judged on the scenes it changes."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import yaml

from harness.study import reading_search as rs
from harness.study.bench.virtualrig import in_budget, rule_space
from tests.test_paired import _rows
from tests.test_virtualrig import REPO

CONFIG = """
name: t
output: runs/t
ratios: [0.3]
scenes: [{name: obj}, {name: room}]
methods:
  - lightgs
  - {name: virtual-rig, variant: vr, sweep: {fov_deg: [40.0, 90.0]}}
"""


def _df(effect):
    """lightgs and every fov value on both scenes, views of three protocols; PSNR = 30 + effect + noise."""
    space = rule_space(yaml.safe_load(CONFIG), "virtual-rig", "vr")
    rng = np.random.default_rng(0)
    rows = []
    for proto in ("rig", "shifted", "independent"):
        noise = rng.normal(0, 0.05, 6)
        for s in space.scenes:
            rows += [dict(r, protocol=proto, view=f"{proto}/{r['view']}") for r in _rows(s, "lightgs", {}, 30 + noise)]
            for fov in (60.0, 40.0, 90.0):
                p = rs.with_value(rs.resolved(space.start, "virtual-rig"), "fov_deg", fov)
                extra = 0.0 if proto == "rig" else effect(fov, s)
                rows += [dict(r, protocol=proto, view=f"{proto}/{r['view']}")
                         for r in _rows(s, "virtual-rig", p, 30 + extra + noise, variant="vr")]
    return space, pd.DataFrame(rows)


def test_an_axis_that_applies_to_one_scene_is_judged_there():
    space, df = _df(lambda fov, s: (1.0 if fov == 40.0 else 0.0) if s == "obj" else 0.0)
    assert space.method == "virtual-rig" and space.reference == {"method": "lightgs"}
    assert space.protocols == ("shifted", "independent")  # the rig protocol never judges
    inc = rs.resolved(space.start, "virtual-rig")
    strict = rs.evaluate_axis(df, space, space.axes[0], inc)
    assert strict.candidate == 40.0 and not strict.adopted  # the room scene's zero difference fails "both"
    step = rs.evaluate_axis(df, space, space.axes[0], inc, ignore_unchanged=True)
    assert step.adopted and step.delta["room"].mean == 0 and step.delta["room"].half_width == 0
    assert step.delta["obj"].mean == pytest.approx(1.0) and step.delta["obj"].n == 12  # shifted + independent
    assert rs.label(space, rs.with_value(inc, "fov_deg", 40.0)) == "vr+fov_deg=40"


def test_a_loss_on_the_other_scene_blocks_adoption_and_unchanged_everywhere_is_no_win():
    _, df = _df(lambda fov, s: 1.0 if fov == 40.0 else 0.0)
    space = rule_space(yaml.safe_load(CONFIG), "virtual-rig", "vr")
    inc = rs.resolved(space.start, "virtual-rig")
    assert rs.evaluate_axis(df, space, space.axes[0], inc, ignore_unchanged=True).adopted
    _, worse = _df(lambda fov, s: (1.0 if s == "obj" else -1.0) if fov == 40.0 else 0.0)
    assert not rs.evaluate_axis(worse, space, space.axes[0], inc, ignore_unchanged=True).adopted
    _, flat = _df(lambda fov, s: 0.0)
    assert not rs.evaluate_axis(flat, space, space.axes[0], inc, ignore_unchanged=True).adopted


def test_budget_and_the_shipped_rule():
    assert in_budget({"views": 48, "resolution": 384}) and in_budget({"views": 96, "resolution": 256})
    assert not in_budget({"views": 96, "resolution": 384}) and not in_budget({"views": 48, "resolution": 512})
    raw = yaml.safe_load((REPO / "ctc_configs" / "study" / "virtualrig.yaml").read_text())
    space = rule_space(raw, "virtual-rig", "vr")
    assert [a.name for a in space.axes] == ["resolution", "views", "fov_deg", "radius_min", "early_stop"]
    # the defaults first: since the outcome, resolution 384 (the rule started from 256)
    assert [a.values[0] for a in space.axes] == [384, 48, 60.0, 0.6, True]
    beta = rule_space(raw, "betadesc-vr", "bvr")
    assert [(a.name, a.values) for a in beta.axes] == [("vr_weight", (1.0, 0.25, 4.0))]
