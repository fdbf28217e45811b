"""Run config: schema defaults, sweep expansion into stable variants, and one clear error per mistake."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from harness.core.errors import InputError
from harness.core.params import Params, param
from harness.run.config import load_config, merge_ratios, parse_config
from methods.registry import register_pruner

REPO = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class FakeConfigParams(Params):
    a: int = param(1, doc="an integer")
    b: str = param("x", doc="a string")
    voxel: float = param(0.01, gt=0, doc="a positive number")


@register_pruner("fake-config", params=FakeConfigParams)
def _fake(scene, ctx):
    """Config test pruner (never run)."""
    raise AssertionError("not called")


def _doc(**over):
    doc = {"scenes": ["luigi"], "methods": ["fake-config"], "ratios": [0.1, 0.2]}
    doc.update(over)
    return doc


def _err(doc) -> str:
    with pytest.raises(InputError) as info:
        parse_config(doc, "c.yaml")
    return str(info.value)


def test_defaults_and_ratio_merge():
    cfg = parse_config(_doc(keep=[0.7, 0.5]), "runs/x.yaml")
    assert cfg.name == "x" and cfg.output == "runs/x" and cfg.workers == 1
    assert cfg.protocol.longest_side == 1024 and cfg.protocol.metrics == ("psnr", "ssim", "lpips")
    assert cfg.scenes[0].source == "luigi" and cfg.scenes[0].label == "luigi"
    (m,) = cfg.methods
    assert (m.method, m.variant, m.params) == ("fake-config", "default", FakeConfigParams())
    assert m.ratios == (0.1, 0.2, 0.3, 0.5)  # keep 0.7 -> ratio 0.3, merged and sorted
    assert merge_ratios([0.3], [0.7]) == (0.3,)


def test_sweeps_expand_to_stable_variant_names():
    cfg = parse_config(_doc(methods=[
        {"name": "fake-config", "sweep": {"b": ["p", "q"], "a": [1, 2]}},
        {"name": "fake-config", "variant": "v", "params": {"a": 3}, "sweep": {"voxel": [0.02]}, "keep": [0.7]},
    ]), "c.yaml")
    names = [m.variant for m in cfg.methods]
    assert names == ["b=p,a=1", "b=p,a=2", "b=q,a=1", "b=q,a=2", "v:voxel=0.02"]
    assert cfg.methods[1].params == FakeConfigParams(b="p", a=2)
    assert cfg.methods[4].params == FakeConfigParams(a=3, voxel=0.02) and cfg.methods[4].ratios == (0.3,)


def test_env_expansion_in_paths(monkeypatch):
    monkeypatch.delenv("MPEG_CTC_ROOT", raising=False)
    doc = _doc(scenes=[{"name": "s", "frames": "${MPEG_CTC_ROOT:-data/mpeg}/s/*.ply"}])
    assert parse_config(doc, "c.yaml").scenes[0].frames == "data/mpeg/s/*.ply"
    monkeypatch.setenv("MPEG_CTC_ROOT", "/mnt/ctc")
    assert parse_config(doc, "c.yaml").scenes[0].frames == "/mnt/ctc/s/*.ply"


@pytest.mark.parametrize(
    "over, expected",
    [
        ({"bogus": 1}, "top level: unknown key 'bogus'; known: anchor,"),
        ({"ratio": [0.1]}, "top level: unknown key 'ratio' (did you mean 'ratios'?)"),
        ({"methods": ["no-such-pruner"]}, "methods[0].name: unknown method 'no-such-pruner'; known: "),
        ({"methods": ["opacty"]}, "methods[0].name: unknown method 'opacty' (did you mean 'opacity'?); known: "),
        (
            {"methods": [{"name": "fake-config", "params": {"c": 1}}]},
            "methods[0].params.c: method 'fake-config': no such parameter; known: a, b, voxel",
        ),
        (
            {"methods": [{"name": "fake-config", "params": {"voxel": -1}}]},
            "methods[0].params.voxel: method 'fake-config': -1.0 is not > 0",
        ),
        (
            {"methods": [{"name": "fake-config", "sweep": {"a": [1, "abc"]}}]},
            "methods[0].sweep.a: method 'fake-config': expected an integer, got 'abc'",
        ),
        (
            {"methods": [{"name": "betadesc", "params": {"gamma": "abc"}}]},
            "methods[0].params.gamma: method 'betadesc': expected a number, got 'abc'",
        ),
        (
            {"methods": [{"name": "betadesc", "params": {"score": "nonsense"}}]},
            "methods[0].params.score: method 'betadesc': 'nonsense' is not one of ucb, lcb, quantile, literal",
        ),
        (
            {"methods": [{"name": "betadesc", "params": {"voxel": -1}}]},
            "methods[0].params.voxel: method 'betadesc': -1.0 is not > 0",
        ),
        (
            {"methods": [{"name": "betadesc", "params": {"max_nn": 2.5}}]},
            "methods[0].params.max_nn: method 'betadesc': expected an integer, got 2.5",
        ),
        ({"methods": [{"name": "fake-config", "params": [1]}]}, "methods[0].params: expected a mapping"),
        ({"methods": [{"name": "fake-config", "sweep": {"a": 3}}]}, "methods[0].sweep.a: expected a non-empty list"),
        (
            {"methods": [{"name": "fake-config", "params": {"a": 1}, "sweep": {"a": [2]}}]},
            "methods[0].sweep.a: also set in params",
        ),
        ({"methods": ["fake-config", "fake-config"]}, "variant fake-config[default] already defined by methods[0]"),
        (
            {"methods": [{"name": "fake-config", "scenes": ["nope"]}]},
            "methods[0].scenes[0]: unknown scene of this config 'nope'",
        ),
        ({"ratios": [0.1, 1.5]}, "ratios[1]: 1.5 is outside [0.0, 1.0]"),
        ({"ratios": "0.1"}, "ratios: expected a non-empty list"),
        ({"ratios": None}, "ratios: expected a non-empty list"),
        ({"scenes": []}, "scenes: expected a non-empty list"),
        ({"scenes": ["a", "a"]}, "scenes[1].name: duplicate scene name 'a'"),
        ({"scenes": [{"name": "a", "source": "x", "frames": "y"}]}, "scenes[0]: give either `source` or `frames`"),
        (
            {"scenes": [{"name": "a", "kind": "360"}]},
            "scenes[0].kind: unknown value '360'; known: forward-facing, object-centric",
        ),
        ({"scenes": [{"name": "a", "cameras": {"path": "c.json"}}]}, "scenes[0].cameras: give the held-out views"),
        ({"protocol": {"longest_side": 12.5}}, "protocol.longest_side: expected an integer"),
        ({"protocol": {"renderer": "vulkan"}}, "protocol.renderer: unknown value 'vulkan'; known: gl, reference"),
        ({"protocol": {"metrics": ["psnr", "flip"]}}, "protocol.metrics[1]: unknown metric or metric set 'flip'"),
        (
            {"protocol": {"metrics": ["ssimm"]}},
            "protocol.metrics[0]: unknown metric or metric set 'ssimm' (did you mean 'ssim'",
        ),
        ({"protocol": {"background": [0, 0]}}, "protocol.background: expected three numbers"),
        ({"tables": ["comparison", "table9"]}, "tables[1]: unknown table 'table9'"),
        ({"workers": 0}, "workers: 0 is outside [1, 256]"),
    ],
)
def test_errors_name_the_key_and_the_problem(over, expected):
    msg = _err(_doc(**over))
    assert msg.startswith("c.yaml: ") and expected in msg


def test_load_config_file_errors(tmp_path):
    with pytest.raises(InputError, match="cannot read config"):
        load_config(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("scenes: [luigi\nmethods: x\n")
    with pytest.raises(InputError, match=r"invalid YAML at line \d+, column \d+"):
        load_config(bad)
    top = tmp_path / "list.yaml"
    top.write_text("- a\n- b\n")
    with pytest.raises(InputError, match="top level: expected a mapping"):
        load_config(top)


@pytest.mark.parametrize("name", ["ci", "default", "nightly", "full", "ctc"])
def test_shipped_configs_are_valid(name):
    cfg = load_config(REPO / "ctc_configs" / f"{name}.yaml")  # every pruner it names is registered
    assert cfg.scenes and cfg.methods
    if name == "ctc":
        suites = {t for s in cfg.scenes for t in s.suites}
        assert {"paper-table1", "subset14", "suite19"} <= suites
        assert sum("suite19" in s.suites and s.kind == "object-centric" for s in cfg.scenes) == 12
        assert all(s.sequence and "${" not in s.sequence for s in cfg.scenes)  # MPEG content folders
        assert not any(s.test or s.test_every for s in cfg.scenes)  # every camera of the content
        assert "mpeg" not in cfg.protocol.metrics and "yuv_psnr_om" in cfg.protocol.metrics


def _with_executor(value):
    return parse_config({"scenes": [{"name": "luigi"}], "methods": ["opacity"], "ratios": [0.1], "executor": value},
                        "x.yaml")


def test_executor_section():
    assert _with_executor("ray").executor.name == "ray"
    spec = _with_executor({"name": "ray", "address": "auto", "cpus_per_task": 4, "gpus_per_task": 0.5,
                           "max_retries": 0}).executor
    assert (spec.address, spec.cpus_per_task, spec.gpus_per_task, spec.max_retries) == ("auto", 4, 0.5, 0)
    assert parse_config({"scenes": [{"name": "luigi"}], "methods": ["opacity"], "ratios": [0.1]},
                        "x.yaml").executor.name == "local"


@pytest.mark.parametrize("value, message", [
    ("dask", "unknown value 'dask'; known: local, ray"),
    ({"name": "local", "address": "auto"}, "go with `name: ray`"),
    ({"name": "ray", "cpus": 2}, "unknown key"),
    ({"name": "ray", "cpus_per_task": 0}, "outside"),
    ({"name": "ray", "max_retries": 1.5}, "integer"),
])
def test_bad_executor_section_is_one_line(value, message):
    with pytest.raises(InputError, match=message):
        _with_executor(value)
