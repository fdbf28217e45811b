"""`extends:` and `harness config show`: a config states only its differences from the one it
extends, resolves to the same study it did as a full copy, and every value says where it came from."""

from __future__ import annotations

from pathlib import Path

import pytest

from harness.core.errors import InputError
from harness.run.config import load_config
from harness.run.config.files import read_config_file
from harness.run.config.show import show

REPO = Path(__file__).resolve().parent.parent
BASE = """name: base
workers: 2
protocol:
  longest_side: 256
  n_test: 3
ratios: [0.1, 0.3]
scenes: [luigi, grape-small]
methods: [opacity, random]
tables: [comparison]
"""


def _write(tmp_path, name, text) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_mappings_merge_and_lists_replace(tmp_path):
    _write(tmp_path, "base.yaml", BASE)
    child = _write(tmp_path, "child.yaml", "extends: base.yaml\nname: child\nprotocol: {longest_side: 64}\n"
                                          "scenes: [luigi]\n")
    cfg = load_config(child)
    assert (cfg.name, cfg.workers, cfg.protocol.longest_side, cfg.protocol.n_test) == ("child", 2, 64, 3)
    assert [s.name for s in cfg.scenes] == ["luigi"] and [m.method for m in cfg.methods] == ["opacity", "random"]
    assert "extends" not in cfg.raw and cfg.raw["protocol"] == {"longest_side": 64, "n_test": 3}
    doc, origins = read_config_file(child)
    assert origins[("protocol", "longest_side")] == f"{child}:3"
    assert origins[("protocol", "n_test")] == f"{tmp_path / 'base.yaml'}:5"
    assert origins[("scenes", 0)] == f"{child}:4" and ("scenes", 1) not in origins  # a list replaced whole


def test_chains_and_their_errors(tmp_path):
    _write(tmp_path, "base.yaml", BASE)
    _write(tmp_path, "mid.yaml", "extends: base.yaml\nworkers: 3\n")
    assert load_config(_write(tmp_path, "top.yaml", "extends: mid.yaml\nname: top\n")).workers == 3
    _write(tmp_path, "a.yaml", "extends: b.yaml\n")
    _write(tmp_path, "b.yaml", "extends: a.yaml\n")
    with pytest.raises(InputError, match="a cycle"):
        load_config(tmp_path / "a.yaml")
    with pytest.raises(InputError, match=r"extends: no such config file .*nope.yaml"):
        load_config(_write(tmp_path, "c.yaml", "extends: nope.yaml\n"))
    with pytest.raises(InputError, match=r"c.yaml: protocol.longest_side: 99999 is outside \[8, 8192\]"):
        load_config(_write(tmp_path, "c.yaml", "extends: base.yaml\nprotocol: {longest_side: 99999}\n"))


@pytest.mark.parametrize("name", ["ci", "full", "nightly"])
def test_shipped_configs_extend_the_default_study(name):
    text = (REPO / "ctc_configs" / f"{name}.yaml").read_text()
    assert "extends: default.yaml" in text
    cfg = load_config(REPO / "ctc_configs" / f"{name}.yaml")
    assert cfg.name == name and cfg.output == f"runs/{name}"


def test_show_prints_every_value_with_its_origin(tmp_path):
    base = _write(tmp_path, "base.yaml", BASE)
    child = _write(tmp_path, "child.yaml", "extends: base.yaml\nname: child\nmethods:\n"
                                          "  - {name: betadesc, params: {gamma: 0.5}, sweep: {voxel: [0.1, 0.2]}}\n")
    out = show(child).splitlines()
    line = {}
    for ln in out:  # the first line of each key (top level before the sections)
        line.setdefault(ln.split(":")[0], ln)
    assert out[0] == f"# {child} (extends {base})"
    assert line["name"].endswith(f"# {child}:2") and line["workers"].endswith(f"# {base}:2")
    assert line["  longest_side"].startswith("  longest_side: 256") and line["  longest_side"].endswith(f"{base}:4")
    assert line["  aspect"].endswith("# default")
    n_test = [ln for ln in out if ln.strip().startswith("n_test")]
    assert n_test[0].endswith(f"{base}:5") and all(ln.endswith(f"{base}:5") for ln in n_test)  # scenes: protocol's
    assert sum("- betadesc[voxel=" in ln for ln in out) == 2
    gamma = [ln for ln in out if "params.gamma" in ln]
    assert len(gamma) == 2 and all("0.5" in ln and ln.endswith(f"{child}:4") for ln in gamma)


def test_config_show_command(capsys):
    from harness.cli import main

    assert main(["config", "show", str(REPO / "ctc_configs" / "full.yaml")]) == 0
    out = capsys.readouterr().out
    assert "(extends" in out and "default.yaml" in out
    assert any(ln.startswith("  longest_side: 1024") and "full.yaml:" in ln for ln in out.splitlines())
    assert main(["config", "show", "no-such.yaml"]) == 2
