"""The house's layers: imports point one way, and no module imports itself back through others.

Every ``import`` statement of the project's own code is read from the source (module level *and*
inside functions: a lazy import is still a dependency), and checked against :data:`ALLOWED`::

    commands/cli → api, benchmarks → run → report → methods → renderers, metrics → views, io → core

``methods`` and ``renderers`` never reach ``harness.run`` or ``harness.report``; ``harness.core``
imports nothing of the project. The paper study (``harness.study``) stands beside the product: it
may import everything but the commands, and nothing of the product imports it (it plugs in through
entry points, as a third-party package does). A cycle between modules (A imports B, which imports A, directly or
through others) fails too, lazily imported or not.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
ROOTS = ("harness", "methods", "renderers")

CORE = {"harness.core"}
IO = CORE | {"harness.io"}
VIEWS = IO | {"harness.views"}
METRICS = IO | {"harness.metrics"}
RENDERERS = CORE | {"renderers"}
METHODS = METRICS | RENDERERS | {"methods"}
REPORT = METHODS | VIEWS | {"harness.report"}
RUN = REPORT | {"harness.run"}
BENCHMARKS = RUN | {"harness.benchmarks"}
API = RUN | {"harness.api"}
COMMANDS = BENCHMARKS | API | {"harness.commands"}
STUDY = BENCHMARKS | API | {"harness.study"}
#: layer of a module (longest matching prefix) -> the layers it may import
ALLOWED = {
    "harness.core": CORE, "harness.io": IO, "harness.views": VIEWS, "harness.metrics": METRICS,
    "renderers": RENDERERS, "methods": METHODS, "harness.report": REPORT, "harness.run": RUN,
    "harness.benchmarks": BENCHMARKS, "harness.api": API, "harness.commands": COMMANDS, "harness.study": STUDY,
    "harness.cli": COMMANDS | {"harness.cli", "harness"}, "harness.__main__": {"harness.cli"},
    "harness": {"harness", "harness.api", "harness.core"},
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def project_modules() -> dict[str, Path]:
    return {module_name(p): p for root in ROOTS for p in (REPO / root).rglob("*.py")}


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """Project modules imported anywhere in ``path`` (submodules resolved where they exist)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in modules:  # `import a.b.c` of a non-module attribute path
                t = t.rpartition(".")[0]
            if t and t.split(".")[0] in ROOTS and t != name:
                out.add(t)
    return out


def layer(name: str) -> str:
    return max((k for k in ALLOWED if name == k or name.startswith(k + ".")), key=len)


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    modules = project_modules()
    return {name: imports_of(name, path, modules) for name, path in modules.items()}


def test_every_module_has_a_layer(graph):
    for name in graph:
        assert layer(name), name


def test_no_upward_imports(graph):
    bad = []
    for name, deps in sorted(graph.items()):
        allowed = ALLOWED[layer(name)]
        for dep in sorted(deps):
            if layer(dep) not in allowed:
                bad.append(f"{name} ({layer(name)}) imports {dep} ({layer(dep)})")
    assert not bad, "upward imports:\n" + "\n".join(bad)


def test_methods_and_renderers_never_reach_run_or_report(graph):
    for name, deps in graph.items():
        if layer(name) in ("methods", "renderers"):
            assert not {d for d in deps if layer(d) in ("harness.run", "harness.report")}, name


def test_the_product_never_imports_the_study(graph):
    assert not any("harness.study" in allowed for name, allowed in ALLOWED.items() if name != "harness.study")
    bad = sorted(f"{name} imports {dep}" for name, deps in graph.items() if layer(name) != "harness.study"
                 for dep in deps if layer(dep) == "harness.study")
    assert not bad, "the product imports the study:\n" + "\n".join(bad)


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's algorithm, iterative; components with more than one module are cycles."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            node, it = work[-1]
            for nxt in it:
                if nxt not in graph:
                    continue
                if nxt not in index:
                    index[nxt] = low[nxt] = counter[0]
                    counter[0] += 1
                    stack.append(nxt)
                    on.add(nxt)
                    work.append((nxt, iter(sorted(graph[nxt]))))
                    break
                if nxt in on:
                    low[node] = min(low[node], index[nxt])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    comp = []
                    while True:
                        m = stack.pop()
                        on.discard(m)
                        comp.append(m)
                        if m == node:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return out


def test_no_import_cycles(graph):
    # a package's __init__ importing its own submodules (re-exports) is not a cycle of modules
    g = {n: {d for d in deps if not d.startswith(n + ".")} for n, deps in graph.items()}
    cycles = strongly_connected(g)
    assert not cycles, "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles)


def test_the_checks_can_fail():
    """The analysis sees lazy imports and finds a planted cycle and an upward import."""
    planted = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}
    assert strongly_connected(planted) == [["a", "b", "c"]]
    assert layer("methods.betadesc.pipeline") == "methods"
    assert "harness.run" not in ALLOWED[layer("methods.registry")]
    modules = project_modules()
    lazy = imports_of("harness.commands.prune", modules["harness.commands.prune"], modules)
    assert any(d.startswith("methods") for d in lazy)  # imported inside run(), still seen


def test_every_imported_name_exists():
    """`from a.b import c` anywhere in the project (inside functions too) names something a.b has:
    a lazy import of a name that was moved or renamed fails here, not in a user's run."""
    import importlib

    modules = project_modules()
    bad = []
    for name, path in sorted(modules.items()):
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not isinstance(node, ast.ImportFrom):
                continue
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                base = ".".join(anchor[: len(anchor) - node.level + 1] + ([base] if base else []))
            if base.split(".")[0] not in ROOTS:
                continue
            mod = importlib.import_module(base)
            for alias in node.names:
                if not hasattr(mod, alias.name) and f"{base}.{alias.name}" not in modules:
                    bad.append(f"{name}: from {base} import {alias.name}")
    assert not bad, "imports of names that do not exist:\n" + "\n".join(bad)
