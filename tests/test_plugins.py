"""Plugins are guests (:mod:`harness.core.plugins`): a failing one is skipped, named, and taken back.

Each test installs small distributions into a folder of its own (a module and a ``.dist-info`` with
its entry points, what ``pip install --target`` leaves) and points the registries at them with
``HARNESS_PLUGINS``, in this process; the registries' state is restored after each test.
"""

from __future__ import annotations

import json
import logging
import sys
import textwrap

import numpy as np
import pytest

from harness.core import plugins
from harness.core.registry import RegistrationError
from harness.metrics.registry import FAMILIES, METRICS, register_metric
from methods.registry import PRUNERS, get_pruner
from tests.scene_factory import random_scene


@pytest.fixture
def site(tmp_path, monkeypatch):
    """``add(dist, group, code)`` installs a distribution; registries and visits are restored after."""
    monkeypatch.syspath_prepend(str(tmp_path))
    for reg in (PRUNERS, METRICS):
        reg._all()  # built-ins and whatever is installed, before the test's own
        monkeypatch.setattr(reg, "_entries", dict(reg._entries))
        monkeypatch.setattr(reg, "_guests", dict(reg._guests))
        monkeypatch.setattr(reg, "_plugins_loaded", False)
    monkeypatch.setattr(plugins, "_visits", {})
    monkeypatch.setattr("harness.metrics.registry.FAMILIES", dict(FAMILIES))
    dists = []

    def add(dist: str, group: str, code: str, entry: str = "p"):
        module = dist.replace("-", "_")
        monkeypatch.delitem(sys.modules, module, raising=False)  # imported again, from this test's folder
        (tmp_path / f"{module}.py").write_text(textwrap.dedent(code))
        info = tmp_path / f"{module}-0.1.dist-info"
        info.mkdir()
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1\n")
        (info / "entry_points.txt").write_text(f"[{group}]\n{entry} = {module}\n")
        dists.append(dist)
        monkeypatch.setenv(plugins.ENV, ",".join(dists))
    yield add
    for d in dists:
        sys.modules.pop(d.replace("-", "_"), None)


def _visit(dist: str) -> plugins.Visit:
    return next(v for v in plugins.records() if v.distribution == dist)


GOOD = """
    from methods.registry import register_pruner
    import numpy as np

    @register_pruner("plugin-good")
    def good(scene, ctx):
        '''Keep large x.'''
        return scene.means[:, 0].astype(np.float64)
"""


def test_a_plugin_that_raises_on_import_is_skipped_and_named(site, caplog):
    site("good-pruner", "harness.pruners", GOOD)
    site("broken-pruner", "harness.pruners", "raise ImportError('needs numpyy')")
    with caplog.at_level(logging.WARNING, logger="harness.plugins"):
        names = PRUNERS.names()
    assert "plugin-good" in names and "opacity" in names
    v = _visit("broken-pruner")
    assert v.status == "skipped" and v.reason == "ImportError: needs numpyy"
    (line,) = [r.getMessage() for r in caplog.records if "broken-pruner" in r.getMessage()]
    assert "broken-pruner 0.1 (entry point harness.pruners: p = broken_pruner) skipped: ImportError" in line
    assert _visit("good-pruner").registered == ["pruner 'plugin-good'"]


def test_sys_exit_in_a_plugin_does_not_end_the_host(site):
    site("quitting", "harness.pruners", "import sys\nsys.exit(3)")
    assert "opacity" in PRUNERS.names()
    assert _visit("quitting").reason == "it called sys.exit(3) while being imported"


def test_what_a_failing_plugin_registered_is_taken_back(site):
    code = textwrap.dedent(GOOD).replace("plugin-good", "plugin-half") + "\nraise RuntimeError('late')\n"
    site("half-done", "harness.pruners", code)
    assert "plugin-half" not in PRUNERS.names()
    assert _visit("half-done").status == "skipped" and _visit("half-done").registered == ["pruner 'plugin-half'"]


def test_a_plugin_never_shadows_a_built_in(site):
    site("shadow", "harness.pruners", """
        from methods.registry import register_pruner

        @register_pruner("opacity")
        def opacity(scene, ctx):
            raise AssertionError("the plugin's opacity ran")
    """)
    assert "opacity" in PRUNERS.names() and get_pruner("opacity").fn.__module__ == "methods.simple"
    v = _visit("shadow")
    assert v.status == "skipped" and "the name is taken by a built-in" in v.reason


def test_a_second_plugin_never_takes_the_first_ones_name(site):
    site("first-one", "harness.pruners", GOOD)
    site("second-one", "harness.pruners", GOOD.replace("Keep large x", "Other"))
    PRUNERS.names()
    assert _visit("first-one").status == "loaded"
    assert "taken by the plugin first-one 0.1" in _visit("second-one").reason


def test_harness_plugins_narrows_the_visited_distributions(site, monkeypatch):
    site("good-pruner", "harness.pruners", GOOD)
    monkeypatch.setenv(plugins.ENV, "none")
    assert "plugin-good" not in PRUNERS.names() and plugins.records() == []
    monkeypatch.setattr(PRUNERS, "_plugins_loaded", False)
    monkeypatch.setenv(plugins.ENV, "Good_Pruner")  # PEP 503: the same distribution
    assert "plugin-good" in PRUNERS.names()


def test_an_error_raised_in_plugin_code_names_the_plugin(site):
    site("boom-pruner", "harness.pruners", """
        from methods.registry import register_pruner

        @register_pruner("boom")
        def boom(scene, ctx):
            return 1 / 0
    """)
    from harness.cli import _unexpected_line

    with pytest.raises(ZeroDivisionError) as err:
        get_pruner("boom").score(random_scene(5), __import__("methods").PruneContext())
    line = _unexpected_line("prune", err.value)
    assert "raised by the plugin boom-pruner 0.1 (entry point harness.pruners: p = boom_pruner)" in line
    assert "this is a bug" not in line
    try:
        1 / 0
    except ZeroDivisionError as own:
        assert "this is a bug" in _unexpected_line("prune", own)


def test_a_wrong_metric_registration_is_one_line_naming_the_field(site):
    site("wrong-metric", "harness.metrics", """
        from harness.metrics import register_metric
        register_metric("mae", lambda a, b: 0.0, higher_is_better=False, cost="gpu")
    """)
    assert "mae" not in METRICS.names()
    assert _visit("wrong-metric").reason == \
        "RegistrationError: metric 'mae': cost must be one of lpips, ssim, psnr, got 'gpu'"


@pytest.mark.parametrize("kwargs, field", [
    ({"higher_is_better": "yes"}, "higher_is_better must be True or False"),
    ({"higher_is_better": True, "valid_range": (1, 0)}, "valid_range (1, 0) is empty"),
    ({"higher_is_better": True, "digits": 2.5}, "digits must be a whole number"),
    ({"higher_is_better": True, "tolerance": -1}, "tolerance must be a finite number >= 0"),
    ({"higher_is_better": True, "family": "gt"}, "a name starting with 'gt_'"),
    ({"higher_is_better": True, "check": 3}, "check must be a function"),
])
def test_every_field_of_a_metric_is_checked(site, kwargs, field):
    with pytest.raises(RegistrationError, match="^metric 'x1': " + field.replace("(", r"\(").replace(")", r"\)")):
        register_metric("x1", lambda a, b: 0.0, **kwargs)
    with pytest.raises(RegistrationError, match="compute must take two images"):
        register_metric("x2", lambda a: 0.0, higher_is_better=True)
    with pytest.raises(TypeError, match="higher_is_better"):
        register_metric("x3", lambda a, b: 0.0)


def test_the_minimal_metric_registration_has_sound_defaults(site):
    spec = register_metric("x4", lambda a, b: float(np.abs(a - b).mean()), higher_is_better=False)
    assert (spec.cost, spec.valid_range, spec.label, spec.digits, spec.family, spec.tolerance) == \
        ("psnr", (-np.inf, np.inf), "x4", 3, "other", None)
    assert METRICS.get("gt_x4").label == "x4 vs photo"


def test_the_plugins_command_lists_loaded_and_skipped(site, capsys):
    from harness.cli import main

    site("good-pruner", "harness.pruners", GOOD)
    site("broken-metric", "harness.metrics", "raise ImportError('needs numpyy')")
    assert main(["plugins", "--json"]) == 0
    rows = {r["distribution"]: r for r in json.loads(capsys.readouterr().out)}
    assert rows["good-pruner"]["status"] == "loaded" and rows["good-pruner"]["registered"] == ["pruner 'plugin-good'"]
    assert rows["broken-metric"]["status"] == "skipped" and rows["broken-metric"]["reason"].startswith("ImportError")
    assert main(["plugins"]) == 0
    text = capsys.readouterr().out
    assert "harness.protocols (view protocols): none installed" in text
    assert "skipped  broken-metric 0.1  p = broken_metric  ImportError: needs numpyy" in text


def test_the_tools_own_entry_points_are_always_visited(site, tmp_path, monkeypatch):
    """HARNESS_PLUGINS narrows third-party plugins; an entry point into the tool's own packages (a
    study's tables, say) is part of the tool."""
    info = tmp_path / "host_part-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: host-part\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[harness.pruners]\nown = methods.simple\n")
    monkeypatch.setenv(plugins.ENV, "none")
    PRUNERS.names()
    assert _visit("host-part").status == "loaded"
