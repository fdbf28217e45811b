"""Where a module's source lies and which project modules it depends on, read from the source.

* :func:`find_module_spec` / :func:`module_file`: the file ``import name`` would run, found without
  importing anything: each parent package's spec gives the search path of the next level, and every
  finder of ``sys.meta_path`` is asked (an editable install's finder included). No package
  ``__init__`` is executed (importing BetaDescPrune's statistics or the projection code just to
  find their files pulled in scipy.stats, numba and torch: 2.2 CPU-s per run).
* :func:`project_closure`: the project modules a module depends on, read **statically** from the
  ``import`` statements of their source (module level and inside functions), never from what
  happens to be imported in this process — pruners import their heavy code lazily, inside the
  score function, and a closure over ``sys.modules`` would change between the first run and the
  next.

The stage cache versions what a stage computed by these files' digests
(:mod:`harness.run.cache.versions`); a run's tables and plots are versioned the same way
(:mod:`harness.report.memo`).
"""

from __future__ import annotations

import ast
import sys
from functools import lru_cache
from pathlib import Path

PROJECT_PACKAGES = ("methods", "renderers", "harness")


def find_module_spec(name: str):
    """The module spec ``import name`` would use, found without importing anything: each parent
    package's spec gives the search path of the next level, and every finder of ``sys.meta_path``
    is asked in order (an editable install's finder included). None when nothing finds it."""
    if name in sys.modules:  # already imported: its own spec (the file it runs from)
        spec = getattr(sys.modules[name], "__spec__", None)
        if spec is not None:
            return spec
    parent, _, _ = name.rpartition(".")
    path = None
    if parent:
        pspec = find_module_spec(parent)
        if pspec is None or pspec.submodule_search_locations is None:  # no such package, or a plain module
            return None
        path = list(pspec.submodule_search_locations)
    for finder in sys.meta_path:
        find = getattr(finder, "find_spec", None)
        spec = find(name, path) if find is not None else None
        if spec is not None:
            return spec
    return None


def module_file(module) -> Path | None:
    """Source file of a module object or dotted name (never imported here: :func:`find_module_spec`)."""
    if isinstance(module, str):
        spec = find_module_spec(module)
        return Path(spec.origin) if spec is not None and spec.origin not in (None, "built-in", "frozen") else None
    f = getattr(module, "__file__", None)
    return Path(f) if f else None


@lru_cache(maxsize=None)
def _imports(name: str, path: str, mtime_ns: int) -> tuple[str, ...]:
    """Dotted names imported anywhere in the module's source (relative imports resolved)."""
    package = name if path.endswith("__init__.py") else name.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(Path(path).read_bytes(), path)):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            out += [base] + [f"{base}.{a.name}" for a in node.names]  # `from pkg import submodule`
    return tuple(out)


def project_closure(module_name: str, roots=PROJECT_PACKAGES) -> set[str]:
    """Names of the modules under ``roots`` that ``module_name`` imports, directly or through
    others (statically, see the module docstring); ``module_name`` included."""
    roots = tuple(roots) + (module_name.split(".")[0],)
    seen, todo = set(), [module_name]
    while todo:
        name = todo.pop()
        if name in seen or name.split(".")[0] not in roots:
            continue
        f = module_file(name)
        if f is None or f.suffix != ".py":
            continue
        seen.add(name)
        todo += [d for d in _imports(name, str(f), f.stat().st_mtime_ns) if d not in seen]
    return seen
