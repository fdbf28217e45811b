"""``docs/plugins.md`` works as written: its files make a package that installs and runs.

Every fenced block of the page with a ``title="..."`` is a file; the package's files are copied into
a source folder and installed with ``pip install --target`` (no network), the config into a working
folder, and the commands of the page's pruner, metric and protocol sections run there as they are
printed — with that folder on ``PYTHONPATH`` and ``HARNESS_PLUGINS`` naming the package only, so
nothing else installed on the machine changes what they see. The protocol's study (a real run: GL
renderer, stage cache) must show the plugin's pruner, metric and two instances of its protocol in
its tables; the project's files stay as they were.
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from tests.plugin_support import REPO, harness, pip_install, project_digest

DOC = REPO / "docs" / "plugins.md"
DIST = "my-harness-plugins"
BLOCK = re.compile(r'^```(\w+)(?: title="([^"]+)")?\n(.*?)^```$', re.M | re.S)


def _blocks() -> list[tuple[str, str | None, str]]:
    """(language, title, text) of every fenced block of the page, in order."""
    return [(m.group(1), m.group(2), m.group(3)) for m in BLOCK.finditer(DOC.read_text())]


def _section_commands(heading: str) -> list[list[str]]:
    """The ``harness`` commands of the bash blocks under ``## heading`` (comments dropped)."""
    text = DOC.read_text().split(f"\n## {heading}\n", 1)[1].split("\n## ", 1)[0]
    out = []
    for m in BLOCK.finditer(text):
        if m.group(1) == "bash":
            out += [shlex.split(line.split("#", 1)[0]) for line in m.group(3).splitlines() if line.strip()]
    assert out and all(c[0] == "harness" for c in out), out
    return out


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> tuple[Path, Path]:
    """(site, work folder): the page's package installed, its config and a scene in the work folder."""
    root = tmp_path_factory.mktemp("docs-plugin")
    src, work = root / "my-harness-plugins", root / "work"
    work.mkdir()
    for lang, title, body in _blocks():
        if title is None:
            continue
        dest = (work if lang == "yaml" else src) / title
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_text(body)
    assert {p.name for p in (src / "my_plugins").iterdir()} >= {"pruners.py", "metrics.py", "protocols.py"}
    from harness.io.ply import write_ply
    from tests.scene_factory import random_scene

    write_ply(random_scene(400, sh_degree=1, seed=11), work / "scene.ply")
    return pip_install(src, root / "site"), work


def _run(installed, argv: list[str]):
    site, work = installed
    assert argv[0] == "harness"
    done = harness(site, DIST, *argv[1:], cwd=work)
    assert done.returncode == 0, f"{shlex.join(argv)}: {done.stderr[-2000:]}"
    return done


def test_the_package_loads_every_plugin(installed):
    done = _run(installed, ["harness", "plugins", "--json"])
    visits = {(v["group"], v["status"]): v for v in json.loads(done.stdout) if v["distribution"] == DIST}
    assert visits[("harness.pruners", "loaded")]["registered"] == ["pruner 'bright'"]
    assert visits[("harness.metrics", "loaded")]["registered"] == ["metric 'mae'", "metric 'gt_mae'"]
    assert visits[("harness.protocols", "loaded")]["registered"] == ["view protocol 'above'"]
    listed = _run(installed, ["harness", "plugins"]).stdout
    assert "loaded   my-harness-plugins 0.1.0  mae = my_plugins.metrics  metric 'mae'" in listed


def test_the_pruner_section_runs_as_written(installed):
    from harness.io.scenes import load_scene

    for argv in _section_commands("A pruner"):
        _run(installed, argv)
    site, work = installed
    assert len(load_scene(work / "pruned.ply")) == 400 - round(0.3 * 400)
    methods = json.loads(_run(installed, ["harness", "methods", "--json"]).stdout)
    bright = next(m for m in methods if m["name"] == "bright")
    assert bright["params"]["opacity_weight"]["default"] == 1.0 and bright["summary"].startswith("Keep bright")


def test_the_metric_section_runs_as_written(installed):
    from PIL import Image

    site, work = installed
    rng = np.random.default_rng(1)
    a = (rng.random((12, 16, 3)) * 255).astype(np.uint8)
    b = np.clip(a.astype(int) + rng.integers(-20, 20, a.shape), 0, 255).astype(np.uint8)
    Image.fromarray(a).save(work / "a.png")
    Image.fromarray(b).save(work / "b.png")
    (argv,) = _section_commands("A metric")
    out = _run(installed, argv).stdout
    got = float(next(line.split()[1] for line in out.splitlines() if line.startswith("mae")))
    assert got == pytest.approx(np.abs(a / 255.0 - b / 255.0).mean(), rel=1e-4)


@pytest.mark.gl
def test_the_protocol_section_runs_a_study_with_every_plugin(installed):
    import pandas as pd

    before = project_digest()
    site, work = installed
    (argv,) = _section_commands("A view protocol")
    done = harness(site, DIST, *argv[1:], cwd=work)
    if done.returncode and "EGL" in done.stderr:
        pytest.skip(f"no EGL OpenGL context here: {done.stderr.strip()[-200:]}")
    assert done.returncode == 0, done.stderr[-3000:]
    tables = work / "runs" / "above" / "tables"
    for proto in ("above", "steep"):
        md = (tables / f"comparison-{proto}.md").read_text()
        assert f"held-out views: {proto}" in md and "Bright" in md and "mae (↓)" in md
    assert "views from high above the scene, all around it" in (tables / "comparison-above.md").read_text()
    res = pd.read_csv(work / "runs" / "above" / "results.csv")
    ok = res[res["status"] == "ok"]
    assert set(ok["protocol"]) == {"rig", "above", "steep"}
    assert ok.loc[ok["protocol"] == "above", "view"].str.startswith("above/above_").all()
    assert ok["mae"].between(0, 1).all() and (ok.loc[ok["method"] == "bright", "mae"] > 0).any()
    per_protocol = ok.groupby("protocol").size()
    assert per_protocol["above"] == per_protocol["steep"] == per_protocol["rig"]
    assert project_digest() == before  # no project file touched
