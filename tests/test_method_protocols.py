"""A method entry's ``protocols:``: its pruned sets are measured only under those of the config's
held-out view protocols — in the config (checked names), the run (rows, renders, scoring) and the
estimate (image counts)."""

from __future__ import annotations

import pytest

from harness.core.errors import InputError
from harness.io.ply import write_ply
from harness.run.config import parse_config
from harness.run.estimate import Assumptions, estimate, scene_info
from tests import runner_fakes as fakes
from tests.scene_factory import random_scene
from tests.test_runner import _config, _run


@pytest.fixture
def scenes(tmp_path):
    return fakes.write_two_scenes(tmp_path)


def test_entry_protocols_are_checked_names(scenes):
    cfg = _config({"s0": scenes["s0"]}, ["random", {"name": "opacity", "protocols": ["rig"]}],
                  protocols=["rig", "shifted"])
    assert [m.protocols for m in cfg.methods] == [None, ("rig",)]
    assert cfg.methods[1].measures("rig") and not cfg.methods[1].measures("shifted")
    with pytest.raises(InputError, match=r"methods\[1\]\.protocols\[0\]: .*'shiftd'.*did you mean 'shifted'"):
        _config({"s0": scenes["s0"]}, ["random", {"name": "opacity", "protocols": ["shiftd"]}],
                protocols=["rig", "shifted"])
    with pytest.raises(InputError, match=r"methods\[0\]\.protocols: expected a non-empty list"):
        _config({"s0": scenes["s0"]}, [{"name": "opacity", "protocols": []}])


def test_a_method_is_measured_only_under_its_protocols(scenes, tmp_path):
    cfg = _config({"s0": scenes["s0"]}, ["random", {"name": "opacity", "protocols": ["rig"]}],
                  protocols=["rig", "shifted"])
    fakes.CALLS.clear()
    res, df = _run(cfg, tmp_path)
    assert (df["status"] == "ok").all()
    seen = {(m, p) for m, p in zip(df["method"], df["protocol"])}
    assert seen == {("random", "rig"), ("random", "shifted"), ("opacity", "rig")}
    # 2 ratios x 2 views per (method, protocol) measured; nothing of opacity under shifted
    assert df.groupby(["method", "protocol"]).size().to_dict() == {
        ("opacity", "rig"): 4, ("random", "rig"): 4, ("random", "shifted"): 4}
    # the rendered sets: 2 views x 2 protocols x random's 2 ratios + 2 views x opacity's 2 (rig only)
    assert res.counts["metrics"]["misses"] == 2 * 2 * 2 + 2 * 2


def test_the_estimate_counts_only_the_measured_images(tmp_path):
    write_ply(random_scene(100, seed=1), tmp_path / "a.ply")
    doc = {"protocol": {"longest_side": 64, "n_test": 3, "n_train": 4, "metrics": ["psnr"]},
           "protocols": ["rig", "shifted"], "ratios": [0.1, 0.3],
           "scenes": [{"name": "a", "source": str(tmp_path / "a.ply")}],
           "methods": ["random", {"name": "opacity", "protocols": ["shifted"]}]}
    config = parse_config(doc, str(tmp_path / "t.yaml"))
    est = estimate(config, [scene_info(s, config, Assumptions()) for s in config.scenes], None)
    # random: 2 ratios x 6 views; opacity: 2 ratios x the 3 shifted views
    assert est.stages["render+metrics"].units == 2 * 6 + 2 * 3
    assert est.stages["render_ref"].units == 6 and est.stages["score"].units == 2


def test_a_table_made_for_one_protocol_only_is_a_note_not_a_failure(tmp_path, capsys):
    """The ablation variants measured under rig only: ``ablation`` is written for rig, and its
    absence under shifted is a note (``harness tables`` exits 0), while a table no protocol can make
    is still missing (and fails ``harness tables`` that asked for it)."""
    import json

    from harness.cli import main
    from harness.report.results import write_results
    from harness.report.tables import write_tables
    from tests.test_tables import _rows

    rig = _rows().assign(protocol="rig")
    shifted = rig[rig["method"].isin(["betadesc", "random"])].assign(
        protocol="shifted", view=lambda d: "shifted/" + d["view"].astype(str))
    df = __import__("pandas").concat([rig, shifted], ignore_index=True)
    written = write_tables(df, tmp_path, ["ablation", "keep"])
    assert (tmp_path / "tables" / "ablation.md").exists() and not (tmp_path / "tables" / "ablation-shifted.md").exists()
    assert [n.split(":")[0] for n in written.notes] == ["table ablation-shifted not made for the shifted views",
                                                        "table keep-shifted not made for the shifted views"]
    assert written.missing == []
    write_results(df, tmp_path)
    (tmp_path / "run.json").write_text(json.dumps({"tables": ["ablation", "keep"], "plots": ["curves"]}))
    assert main(["tables", str(tmp_path)]) == 0
    assert "note: table ablation-shifted not made for the shifted views" in capsys.readouterr().err
    page = (tmp_path / "report.html").read_text()  # the page says it as a note too, not as a warning
    assert "2 note(s): tables measured under some protocols only" in page and "warning(s)" not in page
    assert "Not measured under the shifted views" in page
    assert main(["report", str(tmp_path)]) == 0  # report says it as run and tables do
    assert "note: table ablation-shifted not made for the shifted views" in capsys.readouterr().err
    assert main(["tables", str(tmp_path), "--tables", "bd"]) == 2  # no protocol has its anchor
