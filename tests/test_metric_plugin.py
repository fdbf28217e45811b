"""A third-party metric moves in with one module and an entry point and touches no project file.

A separate package (its own ``pyproject.toml``, installed with ``pip install --target`` into a
temporary folder, never into the project's environment) registers the mean absolute error through
the ``harness.metrics`` entry-point group. With that folder on ``PYTHONPATH`` the metric is asked for
by name in ``harness compare --metrics``, measured by ``harness run`` (a real run: GL renderer,
process pool, stage cache) and shown in its tables, and costed by ``harness plan --estimate`` — and
the project's files are byte-for-byte what they were.
"""

from __future__ import annotations

import json
from importlib.metadata import entry_points
from pathlib import Path

import numpy as np
import pytest
import yaml

from tests.plugin_support import harness, install, project_digest

DIST = "mae-metric"
PLUGIN = '''
"""Mean absolute error, a metric of a package that is not the harness."""
import numpy as np

from harness.metrics import register_metric


def mae(reference, test) -> float:
    return float(np.mean(np.abs(np.clip(reference, 0, 1) - np.clip(test, 0, 1))))


register_metric("mae", compute=mae, higher_is_better=False, valid_range=(0.0, 1.0), cost="psnr",
                family="extra", label="MAE", digits=4, doc="mean absolute error over R, G, B")
'''


@pytest.fixture(scope="module")
def plugin_site(tmp_path_factory) -> Path:
    """The plugin package built and installed into a folder of its own."""
    site = install(tmp_path_factory.mktemp("mae"), DIST, {"mae_metric/__init__.py": PLUGIN},
                   {"harness.metrics": {"mae": "mae_metric"}})
    assert list(site.glob("mae_metric-0.1.0.dist-info/entry_points.txt"))
    return site


def _harness(site: Path, *args, cwd: Path):
    return harness(site, DIST, *args, cwd=cwd)


def test_the_plugin_is_not_there_without_its_package():
    assert not [ep for ep in entry_points(group="harness.metrics") if ep.dist and ep.dist.name == DIST]


def test_compare_measures_the_plugin_metric(plugin_site, tmp_path):
    from PIL import Image

    rng = np.random.default_rng(0)
    a = (rng.random((16, 20, 3)) * 255).astype(np.uint8)
    b = np.clip(a.astype(int) + 10, 0, 255).astype(np.uint8)
    Image.fromarray(a).save(tmp_path / "a.png")
    Image.fromarray(b).save(tmp_path / "b.png")
    done = _harness(plugin_site, "compare", "a.png", "b.png", "--metrics", "psnr,mae", "--json", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    want = np.mean(np.abs(a / 255.0 - b / 255.0))
    assert out["mae"] == pytest.approx(want, rel=1e-5) and "psnr" in out


@pytest.mark.gl
def test_run_tables_and_estimate_carry_the_plugin_metric(plugin_site, tmp_path):
    from tests import runner_fakes as fakes

    before = project_digest()
    scenes = fakes.write_two_scenes(tmp_path)
    doc = {"name": "plugin", "protocol": {"longest_side": 32, "metrics": ["psnr", "extra"], "n_train": 3,
                                          "n_test": 2},
           "ratios": [0.1, 0.3], "scenes": [{"name": k, "source": v} for k, v in scenes.items()],
           "methods": ["opacity", "random"], "tables": ["comparison", "versus"], "plots": []}
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(doc))
    done = _harness(plugin_site, "run", "c.yaml", "--out", "run", "--cache", "cache", cwd=tmp_path)
    if done.returncode and "EGL" in done.stderr:
        pytest.skip(f"no EGL OpenGL context here: {done.stderr.strip()[-200:]}")
    assert done.returncode == 0, done.stderr + done.stdout
    import pandas as pd

    res = pd.read_csv(tmp_path / "run" / "results.csv")
    ok = res[res["status"] == "ok"]
    assert ok["mae"].notna().all() and (ok["mae"] > 0).all() and (ok["mae"] < 1).all()
    table = (tmp_path / "run" / "tables" / "comparison.md").read_text()
    assert "MAE (↓)" in table
    tidy = pd.read_csv(tmp_path / "run" / "tables" / "comparison.csv")
    assert "mae" in set(tidy["metric"])

    plan = _harness(plugin_site, "plan", "c.yaml", "--estimate", cwd=tmp_path)
    assert plan.returncode == 0, plan.stderr
    assert "metrics psnr, mae" in plan.stdout and "— per image 0 LPIPS, 0 SSIM, 2 PSNR-like passes" in plan.stdout
    assert project_digest() == before  # no project file touched
