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
finders, as ``import`` would find them but without executing any package ``__init__``
(:mod:`harness.core.sources`, where :func:`find_module_spec`, :func:`module_file` and
:func:`project_closure` live).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from harness.core.sources import (  # noqa: F401  (importable from here, as before)
    PROJECT_PACKAGES,
    find_module_spec,
    module_file,
    project_closure,
)
from harness.run.cache.stage_cache import digest_bytes, digest_json


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
