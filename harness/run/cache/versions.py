"""Code versions in cache keys: the digest of the source a stage runs, so editing that code — and
only that code — invalidates what it produced.

* :func:`code_digest`: sha256 of modules' source (a package: every ``.py`` under its folder).
* :func:`project_closure`: the project modules a module depends on, read **statically** from the
  ``import`` statements of their source (module level and inside functions), never from what
  happens to be imported in this process — pruners import their heavy code lazily, inside the
  score function, and a closure over ``sys.modules`` would change between the first run and the
  next (the same result stored under two keys).
* :class:`Versions`: the digests a run takes once, at its start, per stage.

Nothing here imports the modules it hashes: source files are located with the import system's
finders (:func:`find_module_spec`), as ``import`` would find them but without executing any
package ``__init__`` (importing BetaDescPrune's statistics or the projection code just to find
their files pulled in scipy.stats, numba and torch: 2.2 CPU-s per run).
"""

from __future__ import annotations

import ast
import sys
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from harness.run.cache.stage_cache import digest_bytes, digest_json

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


def code_digest(*modules) -> str:
    """Digest of the source of ``modules`` (module objects or dotted names); a package contributes
    every ``.py`` file under its folder, a plain module its own file."""
    parts = []
    for mod in modules:
        f = module_file(mod)
        if f is None:
            parts.append([mod if isinstance(mod, str) else getattr(mod, "__name__", str(mod)), "builtin"])
            continue
        files = sorted(f.parent.rglob("*.py")) if f.name == "__init__.py" else [f]
        for p in files:
            parts.append([str(p.relative_to(f.parent)), digest_bytes(p.read_bytes())])
    return digest_json(parts)


def module_versions(names) -> str:
    """:func:`code_digest` of the named modules that exist (a missing optional module is skipped)."""
    return code_digest(*[n for n in names if module_file(n) is not None])


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


def callable_version(fn, extra: tuple[str, ...] = ()) -> str:
    """Digest of the code ``fn`` runs: its module's :func:`project_closure` and ``extra`` when the
    module has a source file; otherwise (a function made by ``exec``, in a doctest or a notebook, whose
    ``__module__`` is None or names no file) its compiled code and constants, with ``extra``."""
    name = getattr(fn, "__module__", None)
    if name and module_file(name) is not None:
        return module_versions(tuple(sorted(project_closure(name))) + extra)
    import marshal

    code = getattr(fn, "__code__", None)
    body = marshal.dumps(code) if code is not None else repr(fn).encode()
    return digest_json([digest_bytes(body), module_versions(extra)])


def plugin_metric_modules() -> tuple[str, ...]:
    """The modules of registered metrics that live outside :mod:`harness.metrics` (third-party
    packages, :mod:`harness.metrics.registry`): their source versions the metrics they compute."""
    from harness.metrics.registry import FAMILIES, METRICS

    fns = [f for m in METRICS for f in (m.compute, m.prepare)] + [f.compute for f in FAMILIES.values()]
    mods = {f.__module__ for f in fns if f is not None and getattr(f, "__module__", None)}
    return tuple(sorted(m for m in mods if m != "harness.metrics" and not m.startswith("harness.metrics.")))


@dataclass
class Versions:
    """Code digests that version each stage's results, taken when a run starts."""

    reader: str
    rigs: str
    renderer: str
    metrics: str
    pruners: dict[str, str] = field(default_factory=dict)
    protocols: dict[str, str] = field(default_factory=dict)

    @classmethod
    def of(cls, toolkit) -> Versions:
        return cls(reader=module_versions(toolkit.reader_modules), rigs=module_versions(toolkit.rig_modules),
                   renderer=module_versions(toolkit.renderer_modules),
                   metrics=module_versions(tuple(toolkit.metric_modules) + plugin_metric_modules()))

    def protocol(self, name: str) -> str:
        """Digest of the code a view protocol's views run: its module and every project module it
        imports (as :meth:`pruner`), with the rigs' (its views are built around the scene's rig)."""
        if name not in self.protocols:
            from harness.views.protocols import PROTOCOL_SPECS

            code = callable_version(PROTOCOL_SPECS.get(name).views, ("harness.views.protocols",))
            self.protocols[name] = digest_json([self.rigs, code])
        return self.protocols[name]

    def pruner(self, name: str) -> str:
        """Digest of the code a pruner runs: its module and every project module it imports,
        directly or through others (LightGS's projection code in ``renderers``, BetaDescPrune's
        pipeline imported inside its score function ...)."""
        if name not in self.pruners:
            from methods.registry import get_pruner

            self.pruners[name] = callable_version(get_pruner(name).fn, ("methods.registry",))
        return self.pruners[name]
