"""The selection driver (:mod:`harness.study.selection`) end to end through ``harness bench
virtualrig select``, with ``harness run`` replaced by a fake that parses each config it is given (the
real parser: the generated stage configs must be valid) and writes PSNRs from known effects. Checked:
only the rule's protocols judge, an over-budget value is never run, an axis that does not apply to a
scene is judged on the scene it changes, betadesc-vr starts from the selected rig, and the stage
configs hold the reference and exactly the parameter sets the walk needs."""

from __future__ import annotations

import json
import zlib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import yaml

from harness.report.results import to_frame
from harness.run.config import parse_config
from harness.study import selection
from harness.study.bench import virtualrig

CONFIG = """
name: t
output: runs/t
ratios: [0.3]
protocols: [rig, shifted, independent]
scenes: [{name: luigi}, {name: bonsai-7k}]
methods:
  - lightgs
  - {name: virtual-rig, variant: vr, sweep: {resolution: [128, 384]}}  # start: resolution 256, below
  - {name: virtual-rig, variant: vr, params: {resolution: 256}, sweep: {views: [24, 96]}}
  - {name: virtual-rig, variant: vr, params: {resolution: 256}, sweep: {fov_deg: [40.0, 90.0]}}
  - {name: virtual-rig, variant: vr, params: {resolution: 256}}
  - {name: betadesc-vr, variant: bvr, sweep: {vr_weight: [4.0]}}
  - {name: betadesc-vr, variant: bvr}
"""


def effect(method: str, p: dict, scene: str, protocol: str) -> float:
    """resolution 384: +1 dB on the rule's protocols, -3 on the rig's (which must not judge); fov 40:
    +0.5 on luigi and nothing at all on bonsai-7k; betadesc-vr's weight 4: -1."""
    if method == "virtual-rig":
        res = (1.0 if protocol != "rig" else -3.0) if p["resolution"] == 384 else 0.0
        return res + (0.5 if p["fov_deg"] == 40.0 and scene == "luigi" else 0.0)
    return -1.0 if method == "betadesc-vr" and p["vr_weight"] == 4.0 else 0.0


def fake_run(root: Path, calls: list):
    def run(config: Path, workers: int, cache: str | None = None) -> float:
        cfg = parse_config(yaml.safe_load(Path(config).read_text()), str(config))
        calls.append((Path(config).name, [(m.method, m.params.to_dict()) for m in cfg.methods]))
        rows = []
        for m in cfg.methods:
            p = m.params.to_dict()
            for s in cfg.scenes:
                for proto in cfg.protocols:
                    for i in range(6):  # per-view noise shared by every side with the same resolution
                        seed = zlib.crc32(f"{s.name}/{proto.name}/{i}/{p.get('resolution')}".encode())
                        noise = np.random.default_rng(seed).normal(0, 0.05)
                        rows.append({"scene": s.name, "method": m.method, "variant": m.variant,
                                     "params": json.dumps(p), "ratio": 0.3, "protocol": proto.name,
                                     "view": f"{proto.name}/v{i}", "status": "ok",
                                     "psnr": 30 + effect(m.method, p, s.name, proto.name) + noise})
        out = root / cfg.output
        out.mkdir(parents=True, exist_ok=True)
        to_frame(rows).to_parquet(out / "results.parquet")
        return 1.0
    return run


def test_select_walks_the_rule_and_runs_only_what_it_needs(tmp_path, monkeypatch, capsys):
    calls = []
    monkeypatch.setattr(selection, "REPO", tmp_path)
    monkeypatch.setattr(selection, "harness_run", fake_run(tmp_path, calls))
    (tmp_path / "t.yaml").write_text(CONFIG)
    args = SimpleNamespace(stage="select", config=str(tmp_path / "t.yaml"), workers=1, out=str(tmp_path / "out"))
    assert virtualrig.select(args) == 0
    capsys.readouterr()

    assert [c[0] for c in calls] == ["t.yaml", "stage-2-views.yaml", "stage-3-fov_deg.yaml", "stage-1-vr_weight.yaml"]
    ran = [(m, p) for _, methods in calls for m, p in methods]
    assert not any(p.get("views") == 96 and p["resolution"] == 384 for _, p in ran)  # over budget: never run
    stage2 = dict(calls)["stage-2-views.yaml"]
    assert stage2[0][0] == "lightgs"  # the reference, then the sets axis 2 needs at the adopted resolution
    # (384, 48) ran with the resolution axis (that entry leaves out only the parameter it sweeps)
    assert sorted((p["resolution"], p["views"]) for m, p in stage2[1:]) == [(384, 24)]
    bvr = [p for m, p in dict(calls)["stage-1-vr_weight.yaml"] if m == "betadesc-vr"]
    assert {(p["resolution"], p["fov_deg"], p["vr_weight"]) for p in bvr} == {(384, 40.0, 1.0), (384, 40.0, 4.0)}

    out = tmp_path / "out"
    selected = json.loads((out / "selected.json").read_text())
    assert selected == {"virtual-rig": {"resolution": 384, "views": 48, "fov_deg": 40.0},
                        "betadesc-vr": {"vr_weight": 1.0}}
    record = json.loads((out / "selection.json").read_text())
    assert record["interval"] == "bootstrap" and record["selected"] == selected["virtual-rig"]
    views = next(s for s in record["steps"] if s["axis"] == "views")
    assert {d["value"] for d in views["d"]} == {48, 24}
    fov = next(s for s in record["steps"] if s["axis"] == "fov_deg")
    assert fov["adopted"] and fov["delta"]["bonsai-7k"]["mean"] == 0  # judged on luigi, where it changes renders
    md = (out / "selection.md").read_text()
    assert (
        "vs lightgs at 30% pruning (dB) over the held-out views of the shifted and independent protocols pooled" in md
    )
    assert "percentile-bootstrap" in md and "### Selected parameters" in md and "| `fov_deg` | `40` |" in md
    assert "## betadesc-vr (on the selected rig)" in md and " of `" not in md
