"""BetaDescPrune's default is the paper as written (paper-literal, voxel 1 % of the diagonal); the
rule-selected readings are named tuned variants; a non-local FPFH radius is announced once."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from harness.cli import main
from harness.core import advice
from methods import get_pruner
from methods.betadesc.params import DEFAULT_READING, READINGS, TUNED_READINGS

REPO = Path(__file__).resolve().parent.parent
PAPER = REPO.parent / "shared" / "paper" / "000_c1a9120657c37710.txt"  # the paper's LaTeX source, beside the repo
ABLATIONS = ("betadesc", "betadesc-nodesc", "betadesc-nobeta", "betadesc-nodesc-nobeta")


def test_methods_json_shows_the_paper_literal_default_with_voxel_one_percent(capsys):
    assert main(["methods", "--json"]) == 0
    listed = {m["name"]: m["params"] for m in json.loads(capsys.readouterr().out)}
    assert listed["betadesc"]["reading"]["default"] == "paper-literal"
    assert listed["betadesc"]["voxel"]["default"] == 0.01
    for name in ABLATIONS:
        assert listed[name]["reading"]["default"] == "paper-literal"


@pytest.mark.parametrize("name", ABLATIONS)
def test_the_default_is_the_paper_literal_bundle_and_the_field_defaults_agree(name):
    spec = get_pruner(name)
    default = spec.parse_params().to_dict()
    named = spec.parse_params({"reading": "paper-literal"}).to_dict()
    assert default == named
    fields = {s.name: s.default for s in spec.params.specs()}
    for key, value in READINGS[DEFAULT_READING].items():
        if key in fields:
            assert fields[key] == value, key  # `harness methods` shows what a run uses


def test_tuned_readings_are_named_and_differ_from_the_default():
    spec = get_pruner("betadesc")
    default = spec.parse_params()
    assert DEFAULT_READING not in TUNED_READINGS
    two = spec.parse_params({"reading": "round-two"})
    assert (two.voxel, two.ell_def) == (0.2, "nbhd-std")
    one = spec.parse_params({"reading": "round-one"})
    assert (one.voxel, one.ell_def) == (0.01, "nbhd-std")
    nodesc = get_pruner("betadesc-nodesc")
    assert nodesc.parse_params({"reading": "round-two"}).nodesc_def == "splat-params"
    assert nodesc.parse_params({"reading": "round-one"}).nodesc_def == "opacity-only"
    assert default.ell_def == "dims-std" and default.voxel == 0.01
    doc = next(s.doc for s in spec.params.specs() if s.name == "reading")
    assert "tuned" in doc and "never the default" in doc


def test_the_voxel_default_quotes_the_paper_sentence_it_reads():
    reading = next(s.reading for s in get_pruner("betadesc").params.specs() if s.name == "voxel")
    assert reading.startswith("L313:")
    if not PAPER.exists():
        pytest.skip(f"the paper is not at {PAPER}")
    line = PAPER.read_text().splitlines()[313 - 1]
    assert "voxel size is set to $1$--$2\\%$ of the scene bounding-box diagonal" in line


@pytest.mark.parametrize("params, warns", [
    ({}, False),                                        # 5 × 1 % = 5 %
    ({"voxel": 0.02}, False),                           # 10 %: still local
    ({"voxel": 0.03}, True),                            # 15 %
    ({"reading": "round-two"}, True),                   # 5 × 0.2 = the whole diagonal
    ({"voxel": 0.05, "radius_voxels": 2.0}, False),     # 10 %
    ({"voxel": 0.01, "radius_voxels": 12.0}, True),     # 12 %
])
def test_a_radius_past_ten_percent_of_the_diagonal_is_not_local(params, warns):
    got = get_pruner("betadesc").parse_params(params).advisories()
    assert bool(got) == warns
    if warns:
        assert len(got) == 1 and "no longer local" in got[0] and "L313" in got[0]


def test_no_descriptor_variants_never_warn():
    assert get_pruner("betadesc-nodesc").parse_params({"reading": "round-two"}).advisories() == []


def test_warn_once_prints_one_line_per_message(capsys):
    msg = "a test advisory that no other test prints"
    assert advice.warn_once(msg) is True
    assert advice.warn_once(msg) is False
    assert capsys.readouterr().err == f"harness: warning: {msg}\n"


def _run(args, cwd):
    return subprocess.run([sys.executable, "-m", "harness", *args], cwd=cwd, capture_output=True, text=True,
                          env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})


def test_a_config_with_a_non_local_variant_warns_once_per_variant(tmp_path):
    scene = tmp_path / "s.ply"
    from harness.io.scenes import write_scene
    from tests.scene_factory import random_scene

    write_scene(random_scene(64, seed=0), scene)
    config = {"name": "w", "scenes": [{"name": "s", "source": str(scene)}], "ratios": [0.3],
              "methods": [{"name": "betadesc", "sweep": {"voxel": [0.01, 0.03, 0.2]}}, "random"],
              "protocol": {"n_test": 2, "longest_side": 32}, "tables": [], "plots": []}
    (tmp_path / "w.yaml").write_text(yaml.safe_dump(config))
    done = _run(["plan", str(tmp_path / "w.yaml")], tmp_path)
    assert done.returncode == 0, done.stderr
    lines = [x for x in done.stderr.splitlines() if "no longer local" in x]
    assert len(lines) == 2, done.stderr
    assert all(x.startswith("harness: warning: ") and "betadesc" in x for x in lines)
    assert "voxel=0.03" in lines[0] and "voxel=0.2" in lines[1]


def test_prune_warns_for_the_tuned_reading_only(tmp_path):
    from harness.io.scenes import write_scene
    from tests.scene_factory import random_scene

    write_scene(random_scene(200, seed=1), tmp_path / "s.ply")
    quiet = _run(["prune", "s.ply", "a.ply", "--ratio", "0.3"], tmp_path)
    assert quiet.returncode == 0 and "no longer local" not in quiet.stderr, quiet.stderr
    loud = _run(["prune", "s.ply", "b.ply", "--ratio", "0.3", "--reading", "round-two"], tmp_path)
    assert loud.returncode == 0, loud.stderr
    assert [x for x in loud.stderr.splitlines() if "no longer local" in x] == [
        "harness: warning: method 'betadesc': FPFH radius = radius_voxels 5 × voxel 0.2 = 100 % of the bounding-box "
        "diagonal (> 10 %): the descriptors are no longer local (the paper's voxel is 1–2 % of the diagonal, L313)"]


def test_a_methods_own_default_is_not_announced_but_a_users_choice_is(capsys):
    """betadesc-vr's default reading carries the non-local advisory (documented with the method);
    announcing its defaults prints nothing, a voxel the user chose past them prints the one line."""
    vr = get_pruner("betadesc-vr")
    assert vr.parse_params({}).advisories(), "betadesc-vr's default reading is round two's (non-local)"
    advice.announce("method 'betadesc-vr' (test defaults)", vr.parse_params({}))
    assert capsys.readouterr().err == ""
    advice.announce("method 'betadesc-vr' (test choice)", vr.parse_params({"voxel": 0.3}))
    err = capsys.readouterr().err
    assert err.count("harness: warning: method 'betadesc-vr' (test choice)") == 1 and "150 %" in err
