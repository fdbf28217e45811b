"""Round two of the virtual rig's selection: the non-inferiority test of its Adoption step and which
selected values move a scene's cameras (what a failed scene revokes)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import yaml

from harness.core.paths import REPO_ROOT
from harness.study.virtualrig_round2 import MARGIN_DB, non_inferiority, rule_space


def _results(gap: float, noise: float) -> pd.DataFrame:
    rng = np.random.default_rng(0)
    base = 40 + rng.normal(size=16)
    jitter = noise * np.tile([1.0, -1.0], 8)
    rows = []
    for variant, values in (("start", base), ("selected", base + gap + jitter)):
        for k, v in enumerate(values):
            rows.append({"status": "ok", "scene": "s", "method": "virtual-rig", "variant": variant, "ratio": 0.3,
                         "view": f"v{k}", "psnr": v, "protocol": "shifted" if k < 8 else "independent",
                         "params": "{}"})
    return pd.DataFrame(rows)


def test_non_inferiority_reads_the_lower_bound():
    assert non_inferiority(_results(-0.2, 0.05), "s")[1] == "non-inferior"
    assert non_inferiority(_results(+1.0, 0.05), "s")[1] == "non-inferior"
    p, verdict = non_inferiority(_results(-0.45, 1.0), "s")  # the mean is within the margin, the interval not
    assert verdict == "inferior" and p.mean > -MARGIN_DB and p.lo <= -MARGIN_DB
    assert non_inferiority(_results(0.0, 0.0), "s")[1] == "not changed"


def test_the_rule_config_is_the_search_it_states():
    raw = yaml.safe_load((REPO_ROOT / "ctc_configs" / "study" / "virtualrig2.yaml").read_text())
    space = rule_space(raw)
    assert space.starts == {"virtual-rig": {"positions": "around", "support": "off"}}
    assert [(a.name, a.values) for a in space.axes] == [("positions", ("around", "coverage")),
                                                        ("support", ("off", "auto"))]
    assert space.protocols == ("shifted", "independent") and space.interval == "t" and space.ratio == 0.3
    assert space.scenes == ("bonsai-7k", "playbot", "luigi")


def test_which_selected_values_move_a_scenes_cameras(tmp_path):
    from harness.io.scenes import write_scene
    from harness.study.virtualrig_round2 import axes_changing
    from tests.test_virtualrig_placement import _room_with_table, _standing_object

    start, selected = {"positions": "around", "support": "off"}, {"positions": "coverage", "support": "auto"}
    for name, scene, moved in (("standing.ply", _standing_object(), ["support"]),
                               ("room.ply", _room_with_table(), ["positions"])):
        path = write_scene(scene, tmp_path / name)
        assert axes_changing(str(path), None, {**start, "views": 8, "resolution": 16},
                             selected) == moved
