"""Plugins are guests (registered into :data:`tests.stress.cases.CASES`): family **P**.

Each case installs a small third-party package into a folder of its own — a module and a
``<dist>.dist-info`` with its entry points, what ``pip install --target`` leaves, written by hand so
a case costs no build — puts that folder on the child's ``PYTHONPATH`` after the tree, and runs one
command that uses only built-ins (or asks for the plugin by name). A plugin that fails to import,
raises, calls ``sys.exit`` or shadows a built-in must be skipped with at most one warning line naming
its distribution and entry point, and the built-ins must keep working; an error raised inside a
plugin's code while it works names the plugin.
"""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import numpy as np

from tests.stress.cases import Setup, _ply, _run_dir, case


def _plugin(d: Path, dist: str, group: str, code: str, entry: str = "p", module: str | None = None) -> Path:
    """A folder holding the distribution ``dist`` 0.1: module ``module`` (``code``) named by the entry
    point ``entry`` of ``group``; returns the folder (for ``Setup.path``)."""
    site = d / "site"
    site.mkdir(exist_ok=True)
    module = module or dist.replace("-", "_")
    (site / f"{module}.py").write_text(textwrap.dedent(code))
    info = site / f"{module}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[{group}]\n{entry} = {module}\n")
    return site


def _warned(dist: str, group: str, *words: str, alone: bool = True):
    """A stderr check: at most one line names the distribution, a warning naming the entry point's
    group and ``words``; with ``alone``, no other stderr line (else the command's own may follow)."""
    def check(out: str, err: str) -> str | None:
        lines = [ln for ln in err.strip().splitlines() if ln.strip()]
        about = [ln for ln in lines if dist in ln]
        if alone and len(lines) > len(about):
            return f"{len(lines) - len(about)} stderr line(s) besides the plugin's warning"
        if len(about) > 1:
            return f"{len(about)} lines name the plugin"
        if about and not ("warning" in about[0] and all(w in about[0] for w in (group, *words))):
            return f"the warning does not name {group} / {' '.join(words)}"
        return None
    return check


def _names(*words: str):
    """A stderr check: the last line names each of ``words`` (the plugin whose code failed)."""
    def check(out: str, err: str) -> str | None:
        last = err.strip().splitlines()[-1] if err.strip() else ""
        missing = [w for w in words if w not in last]
        return f"the error does not name {', '.join(missing)}" if missing else None
    return check


def _prune(d: Path, site: Path, method: str = "opacity", **kw) -> Setup:
    s = _ply(d, 200)
    return Setup(["prune", str(s), str(d / "o.ply"), "--ratio", "0.3", "--method", method], unchanged=[s],
                 path=[site], **kw)


def _pngs(d: Path) -> list[str]:
    from PIL import Image

    rng = np.random.default_rng(0)
    a = (rng.random((16, 16, 3)) * 255).astype(np.uint8)
    Image.fromarray(a).save(d / "a.png")
    Image.fromarray(255 - a).save(d / "b.png")
    return [str(d / "a.png"), str(d / "b.png")]


RAISES = "raise ImportError('this plugin needs numpyy')\n"
EXITS = "import sys\nsys.exit(3)\n"


@case("P1", "plugins", "prune --method opacity with a pruner plugin that raises on import", want="ok")
def _(d):
    site = _plugin(d, "broken-pruner", "harness.pruners", RAISES)
    return _prune(d, site, output_check=_warned("broken-pruner", "harness.pruners", "ImportError"))


@case("P2", "plugins", "prune --method opacity with a pruner plugin that calls sys.exit(3) on import", want="ok")
def _(d):
    site = _plugin(d, "quitting-pruner", "harness.pruners", EXITS)
    return _prune(d, site, output_check=_warned("quitting-pruner", "harness.pruners", "sys.exit"))


@case("P3", "plugins", "prune --method opacity with a plugin that registers its own 'opacity'", want="ok")
def _(d):
    site = _plugin(d, "shadow-pruner", "harness.pruners", """
        from methods.registry import register_pruner

        @register_pruner("opacity")
        def opacity(scene, ctx):
            raise RuntimeError("the plugin's opacity ran instead of the built-in")
    """)
    return _prune(d, site, output_check=_warned("shadow-pruner", "harness.pruners", "opacity"))


@case("P4", "plugins", "info s.ply with a scene-format plugin that raises on import", want="ok")
def _(d):
    site = _plugin(d, "broken-format", "harness.formats", RAISES)
    s = _ply(d, 50)
    return Setup(["info", str(s), "--json"], unchanged=[s], path=[site], strict_json=True,
                 output_check=_warned("broken-format", "harness.formats", "ImportError"))


@case("P5", "plugins", "info s.ply with a scene-format plugin whose detect() raises", want="ok")
def _(d):
    site = _plugin(d, "detect-raises", "harness.formats", """
        from harness.io.formats import register_format

        def detect(probe):
            raise ValueError("cannot look at this file")

        def read(path, lod=None):
            raise ValueError("unreachable")

        register_format("never", label="never", detect=detect, read=read, modules=(__name__,))
    """)
    s = _ply(d, 50)
    return Setup(["info", str(s), "--json"], unchanged=[s], path=[site], strict_json=True,
                 output_check=_warned("detect-raises", "harness.formats", "ValueError"))


@case("P6", "plugins", "compare --metrics psnr with a metric plugin that raises on import", want="ok")
def _(d):
    site = _plugin(d, "broken-metric", "harness.metrics", RAISES)
    return Setup(["compare", *_pngs(d), "--metrics", "psnr", "--json"], path=[site], strict_json=True,
                 output_check=_warned("broken-metric", "harness.metrics", "ImportError"))


@case("P7", "plugins", "harness plugins: a metric plugin registered with cost='gpu' (a wrong field)", want="ok")
def _(d):
    site = _plugin(d, "wrong-metric", "harness.metrics", """
        from harness.metrics import register_metric

        register_metric("mae", compute=lambda a, b: 0.0, higher_is_better=False, cost="gpu")
    """)

    return Setup(["plugins"], path=[site], output_check=_warned("wrong-metric", "harness.metrics", "cost"))


@case("P8", "plugins", "harness plugins lists what loaded and what did not, and why", want="ok")
def _(d):
    site = _plugin(d, "broken-metric", "harness.metrics", RAISES)
    _plugin(d, "good-metric", "harness.metrics", """
        from harness.metrics import register_metric

        register_metric("half", lambda a, b: 0.5, higher_is_better=True)
    """)

    def check(out: str, err: str) -> str | None:
        try:
            listed = {(p.get("distribution"), p.get("status")) for p in json.loads(out)}
        except (ValueError, TypeError, AttributeError):
            return "no JSON list of plugins on stdout"
        want = {("broken-metric", "skipped"), ("good-metric", "loaded")}
        return None if want <= listed else f"listed {sorted(listed)}"
    return Setup(["plugins", "--json"], path=[site], strict_json=True, output_check=check)


@case("P9", "plugins", "harness tables RUN with a table plugin that raises on import", want="ok")
def _(d):
    site = _plugin(d, "broken-table", "harness.tables", RAISES)
    r = _run_dir(d)
    return Setup(["tables", str(r), "--tables", "comparison"], path=[site],
                 output_check=_warned("broken-table", "harness.tables", "ImportError", alone=False))


@case("P10", "plugins", "harness plugins --json with a renderer and a protocol plugin that exit on import", want="ok")
def _(d):
    site = _plugin(d, "quitting-renderer", "harness.renderers", EXITS)
    _plugin(d, "quitting-protocol", "harness.protocols", EXITS)

    def check(out: str, err: str) -> str | None:
        lines = [ln for ln in err.strip().splitlines() if ln.strip()]
        if len(lines) != 2 or not all("quitting-" in ln and "sys.exit(3)" in ln for ln in lines):
            return f"{len(lines)} stderr lines: {lines[-1][:60] if lines else ''}"
        try:
            skipped = {p["distribution"] for p in json.loads(out) if p["status"] == "skipped"}
        except (ValueError, TypeError, KeyError):
            return "no JSON list of plugins on stdout"
        return None if skipped == {"quitting-renderer", "quitting-protocol"} else f"skipped: {sorted(skipped)}"
    return Setup(["plugins", "--json"], path=[site], strict_json=True, output_check=check)


@case("P11", "plugins", "prune --method boom: a plugin pruner that raises while scoring (names the plugin)")
def _(d):
    site = _plugin(d, "boom-pruner", "harness.pruners", """
        from methods.registry import register_pruner

        @register_pruner("boom")
        def boom(scene, ctx):
            raise ZeroDivisionError("the plugin divided by zero")
    """)
    s = _ply(d, 200)
    return Setup(["prune", str(s), str(d / "o.ply"), "--ratio", "0.3", "--method", "boom"], unchanged=[s],
                 absent=[d / "o.ply"], path=[site], output_check=_names("boom-pruner", "ZeroDivisionError"))


@case("P12", "plugins", "prune --method quitter: a plugin pruner that calls sys.exit(3) while scoring")
def _(d):
    site = _plugin(d, "quitter-pruner", "harness.pruners", """
        import sys
        from methods.registry import register_pruner

        @register_pruner("quitter")
        def quitter(scene, ctx):
            sys.exit(3)
    """)
    s = _ply(d, 200)
    return Setup(["prune", str(s), str(d / "o.ply"), "--ratio", "0.3", "--method", "quitter"], unchanged=[s],
                 absent=[d / "o.ply"], path=[site], output_check=_names("quitter-pruner", "sys.exit"))


@case("P13", "plugins", "run a config with opacity beside a pruner plugin that raises on import", want="ok",
      slow=True)
def _(d):
    from tests.stress.cases import _config

    site = _plugin(d, "broken-pruner", "harness.pruners", RAISES)
    c = _config(d)
    return Setup(["run", str(c), "--cache", str(d / "cache")], unchanged=[c, d / "s.ply"], path=[site],
                 output_check=lambda out, err: None if err.count("broken-pruner") == 1 else
                 f"the plugin is named {err.count('broken-pruner')} times on stderr")

