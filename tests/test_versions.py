"""Code versions in cache keys: found from the source alone (nothing imported), and they follow every
module of a pruner's static import closure."""

import json
import subprocess
import sys
import textwrap
from pathlib import Path

from harness.run.cache.versions import callable_version, find_module_spec, module_file, module_versions, project_closure

ROOT = Path(__file__).resolve().parents[1]


def _package(tmp_path, monkeypatch) -> Path:
    """vpkg: a → (inside a function) b → (relative) c, and vpkg/__init__ fails if it is ever run."""
    pkg = tmp_path / "vpkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("raise RuntimeError('vpkg was imported')\n")
    (pkg / "sub" / "__init__.py").write_text("raise RuntimeError('vpkg.sub was imported')\n")
    (pkg / "a.py").write_text("import os\n\ndef f():\n    from vpkg.sub import b\n    return b.g()\n")
    (pkg / "sub" / "b.py").write_text("from . import c\nfrom .c import VALUE\n\ndef g():\n    return VALUE\n")
    (pkg / "sub" / "c.py").write_text("VALUE = 1\n")
    (pkg / "unused.py").write_text("VALUE = 3\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    return pkg


def test_closure_and_digest_without_importing(tmp_path, monkeypatch):
    pkg = _package(tmp_path, monkeypatch)
    mods = project_closure("vpkg.a", roots=())
    assert mods == {"vpkg.a", "vpkg.sub", "vpkg.sub.b", "vpkg.sub.c"}
    assert module_file("vpkg.sub.c") == pkg / "sub" / "c.py"
    assert module_file("vpkg.sub.c.VALUE") is None and find_module_spec("vpkg.nothing") is None
    assert not any(m.startswith("vpkg") for m in sys.modules)  # found, never executed

    def digest():
        return module_versions(sorted(project_closure("vpkg.a", roots=())))

    first = digest()
    assert digest() == first
    (pkg / "unused.py").write_text("VALUE = 4\n")  # outside the closure: same version
    assert digest() == first
    for edited in (pkg / "sub" / "c.py", pkg / "sub" / "b.py", pkg / "a.py", pkg / "sub" / "__init__.py"):
        before = digest()
        edited.write_text(edited.read_text() + "# edited\n")
        assert digest() != before, edited
    assert not any(m.startswith("vpkg") for m in sys.modules)


def test_project_versions_import_nothing_heavy_and_find_the_imported_files():
    """Independent truth: the files the import system loads when the modules are really imported."""
    script = textwrap.dedent("""
        import json, sys
        from harness.run.toolkit import Toolkit
        from harness.run.cache.versions import Versions, module_file, project_closure
        from methods.registry import list_pruners
        v = Versions.of(Toolkit())
        digests = {s.name: v.pruner(s.name) for s in list_pruners()}
        heavy = sorted(m for m in ("torch", "scipy.stats", "numba", "lpips", "sklearn") if m in sys.modules)
        closure = sorted(set().union(*(project_closure(s.fn.__module__) for s in list_pruners())))
        static = {m: str(module_file(m)) for m in closure}
        import importlib
        loaded = {m: importlib.import_module(m).__file__ for m in closure}
        print(json.dumps({"heavy": heavy, "static": static, "loaded": loaded, "n": len(digests)}))
    """)
    out = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, check=True)
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["heavy"] == []
    assert res["n"] >= 9 and len(res["static"]) > 20
    assert res["static"] == res["loaded"]


def _made_by_exec(body: str):
    scope: dict = {}  # no __name__: the function's __module__ is None, as in a doctest with empty globals
    exec(f"def views(scene, seed):\n    return {body}\n", scope)
    return scope["views"]


def test_a_function_without_a_module_is_versioned_by_its_code():
    a, same, other = _made_by_exec("[1]"), _made_by_exec("[1]"), _made_by_exec("[2]")
    assert a.__module__ is None
    assert callable_version(a) == callable_version(same) != callable_version(other)
    assert callable_version(a, ("harness.views.protocols",)) != callable_version(a)


def test_a_project_function_is_versioned_by_its_modules_closure():
    from methods.simple import opacity_score as fn

    want = module_versions(tuple(sorted(project_closure(fn.__module__))) + ("methods.registry",))
    assert callable_version(fn, ("methods.registry",)) == want
