"""Pruner registry: ``@register_pruner`` (like timm's ``@register_model``) plus entry points.

A pruner is a function ``score(scene, ctx) -> float64 (N,)``, higher = keep. It declares its
parameters with defaults and what it needs from the context (``"cameras"``, ``"renderer"``);
the harness skips a pruner whose needs a scene cannot meet and records why.

Built-in pruners live in the modules listed in ``_BUILTIN_MODULES``; third-party packages add
theirs through the ``harness.pruners`` entry-point group: each entry point names a module
(``myname = "mypkg.pruners"``) whose import registers its pruners with :func:`register_pruner`.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from typing import Any, Callable, Mapping

import numpy as np

ENTRY_POINT_GROUP = "harness.pruners"
#: built-in pruner name -> module registering it. ``get_pruner`` imports only the module it needs,
#: so `harness prune --method betadesc` never pays for torch (imported by the camera-aware families).
_BUILTIN_PRUNERS = {
    "opacity": "methods.simple",
    "volume": "methods.simple",
    "random": "methods.simple",
    "betadesc": "methods.betadesc",
    "betadesc-nodesc": "methods.betadesc",
    "betadesc-nobeta": "methods.betadesc",
    "betadesc-nodesc-nobeta": "methods.betadesc",
    "lightgs": "methods.lightgs",
    "confsplat": "methods.confsplat",
}
KNOWN_NEEDS = frozenset({"cameras", "renderer"})

_REGISTRY: dict[str, "PrunerSpec"] = {}
_loaded = False


@dataclass
class PruneContext:
    """What a pruner may use besides the scene.

    ``params`` are the pruner's parameters merged over its declared defaults. ``cameras`` (training
    views) and ``renderer`` are present only for camera-aware runs; ``device`` is the torch device
    name to compute on ("cpu" or "cuda").
    """

    params: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    cameras: list | None = None
    renderer: Any = None
    device: str = "cpu"


@dataclass(frozen=True)
class PrunerSpec:
    name: str
    fn: Callable[..., np.ndarray]
    needs: frozenset[str]
    params: Mapping[str, Any]
    summary: str

    def missing_needs(self, ctx: PruneContext) -> list[str]:
        """Needs the context cannot meet (empty list = runnable)."""
        have = {"cameras": bool(ctx.cameras), "renderer": ctx.renderer is not None}
        return sorted(n for n in self.needs if not have[n])

    def resolve_params(self, params: Mapping[str, Any] | None) -> dict[str, Any]:
        """Defaults overlaid with ``params``; unknown names are an error."""
        params = dict(params or {})
        unknown = sorted(set(params) - set(self.params))
        if unknown:
            raise KeyError(f"pruner {self.name!r} has no parameter(s) {', '.join(unknown)}; "
                           f"known: {', '.join(sorted(self.params)) or 'none'}")
        return {**self.params, **params}

    def score(self, scene, ctx: PruneContext) -> np.ndarray:
        """Run the pruner with resolved params; checks the output contract."""
        ctx = PruneContext(**{**ctx.__dict__, "params": self.resolve_params(ctx.params)})
        missing = self.missing_needs(ctx)
        if missing:
            raise RuntimeError(f"pruner {self.name!r} needs {', '.join(missing)}")
        scores = np.asarray(self.fn(scene, ctx), dtype=np.float64)
        if scores.shape != (len(scene),):
            raise RuntimeError(f"pruner {self.name!r} returned shape {scores.shape}, expected ({len(scene)},)")
        if not np.all(np.isfinite(scores)):
            raise RuntimeError(f"pruner {self.name!r} returned non-finite scores")
        return scores


def register_pruner(
    name: str,
    *,
    needs: tuple[str, ...] | frozenset[str] = (),
    params: Mapping[str, Any] | None = None,
    summary: str | None = None,
):
    """Decorator registering ``fn(scene, ctx) -> scores`` under ``name``.

    ``summary`` defaults to the first line of the function's docstring.
    """
    bad = set(needs) - KNOWN_NEEDS
    if bad:
        raise ValueError(f"unknown needs {sorted(bad)}; known: {sorted(KNOWN_NEEDS)}")

    def deco(fn):
        doc = (fn.__doc__ or "").strip().splitlines()
        spec = PrunerSpec(
            name=name,
            fn=fn,
            needs=frozenset(needs),
            params=dict(params or {}),
            summary=summary or (doc[0] if doc else name),
        )
        if name in _REGISTRY and _REGISTRY[name].fn is not fn:
            raise ValueError(f"pruner {name!r} is already registered by {_REGISTRY[name].fn.__module__}")
        _REGISTRY[name] = spec
        return fn

    return deco


def _load_all() -> None:
    global _loaded
    if _loaded:
        return
    _loaded = True
    for mod in dict.fromkeys(_BUILTIN_PRUNERS.values()):
        importlib.import_module(mod)
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        ep.load()  # importing the named module runs its @register_pruner decorators


def list_pruners() -> list[PrunerSpec]:
    _load_all()
    return [_REGISTRY[k] for k in sorted(_REGISTRY)]


def get_pruner(name: str) -> PrunerSpec:
    if name in _BUILTIN_PRUNERS:
        importlib.import_module(_BUILTIN_PRUNERS[name])
    if name not in _REGISTRY:
        _load_all()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise KeyError(f"unknown pruner {name!r}; known: {', '.join(sorted(_REGISTRY))}") from None
