"""Pruner registry: ``@register_pruner`` (like timm's ``@register_model``) with the metadata every
tool asks it for — parameters, needs, display label, table group and place in the paper's ablation.

A pruner is a function ``score(scene, ctx) -> float64 (N,)``, higher = keep. It declares

* ``params``: a :class:`harness.core.params.Params` dataclass (types, ranges, documentation). Configs,
  ``harness prune`` flags and the runner all validate through it once, at load; the pruner receives
  the resolved instance as ``ctx.params``.
* ``needs``: what the context must hold (``"cameras"``: training views); a run skips a pruner whose
  needs a scene cannot meet and records why.
* ``uses_device``: it computes with torch on ``ctx.device``; a run on a GPU sends its scoring to the
  worker(s) that hold the device, and runs the others on the CPU workers (a pruner that uses the
  device without saying so still works, on a CPU worker that then opens the device itself).
* ``label`` (table/plot name), ``group`` (one of :data:`GROUPS`, the comparison table's column
  groups) and, for the paper's method and its ablations, ``ablation``: its cell of the
  descriptors × Beta grid (Table 2).

Built-in pruners live in :data:`BUILTIN_MODULES` (cheap to import: heavy libraries are imported
inside the score functions); third-party packages add theirs through the ``harness.pruners``
entry-point group (see :mod:`harness.core.registry`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np

from harness.core.errors import HarnessError
from harness.core.params import Params
from harness.core.registry import Registry

ENTRY_POINT_GROUP = "harness.pruners"
#: registration order is display order within a group (tables, plots, `harness methods`)
BUILTIN_MODULES = ("methods.confsplat", "methods.lightgs", "methods.virtualrig", "methods.simple", "methods.betadesc",
                   "methods.betadesc.vr")
KNOWN_NEEDS = frozenset({"cameras"})
#: comparison-table groups, in column order, with their titles
GROUPS = {"camera-aware": "Camera-Aware Methods", "camera-free": "Camera-Free (virtual rig)",
          "baseline": "Simple Baselines", "ours": "Our Method",
          "ablation": "Ablations", "other": "Other Methods"}


@dataclass(frozen=True)
class Ablation:
    """A cell of the paper's ablation grid (Table 2): neighbourhood descriptors on/off × Beta on/off."""

    descriptors: bool
    beta: bool

    @property
    def labels(self) -> tuple[str, str]:
        return ("With Descriptors" if self.descriptors else "No Descriptors", "Beta" if self.beta else "No Beta")


@dataclass(frozen=True)
class NoParams(Params):
    """Parameters of a pruner that has none."""


@dataclass
class PruneContext:
    """What a pruner may use besides the scene.

    ``params`` is the pruner's resolved :class:`Params` instance; ``cameras`` (training views) is
    present only when the run or the command has cameras; ``device`` is the torch device name to
    compute on ("cpu" or "cuda").
    """

    params: Params | None = None
    seed: int = 0
    cameras: list | None = None
    device: str = "cpu"


@dataclass(frozen=True)
class PrunerSpec:
    name: str
    fn: Callable[..., np.ndarray]
    params: type[Params]
    needs: frozenset[str]
    label: str
    group: str
    ablation: Ablation | None
    summary: str
    #: parameters with which the pruner uses cameras when they are given (e.g. betadesc's view_weight
    #: > 0): the runner then hands it the rig's training views although it does not need them
    uses_cameras: Callable[[Params], bool] = field(default=lambda p: False)
    #: a note for tables when these parameters make the pruner's numbers a bound of what it can do
    #: (e.g. ConfSplat trained for fewer iterations than its own default): "lower bound (100 iterations)"
    budget_note: Callable[[Params], str | None] = field(default=lambda p: None)
    #: it computes with torch on ``ctx.device`` (module docstring)
    uses_device: bool = False

    def parse_params(self, values: Mapping[str, Any] | Params | None = None) -> Params:
        """The resolved parameters (``ParamError`` naming the key for a bad one)."""
        return values if isinstance(values, self.params) else self.params.parse(values)

    def wants_cameras(self, params: Params) -> bool:
        """Does a run hand this pruner training cameras (it needs them, or these params use them)?"""
        return "cameras" in self.needs or bool(self.uses_cameras(params))

    def missing_needs(self, ctx: PruneContext) -> list[str]:
        """Needs the context cannot meet (empty list = runnable)."""
        have = {"cameras": bool(ctx.cameras)}
        return sorted(n for n in self.needs if not have[n])

    def score(self, scene, ctx: PruneContext) -> np.ndarray:
        """Run the pruner (parameters resolved if the context holds a mapping); checks the output."""
        ctx = PruneContext(params=self.parse_params(ctx.params), seed=ctx.seed, cameras=ctx.cameras,
                           device=ctx.device)
        missing = self.missing_needs(ctx)
        if missing:
            raise RuntimeError(f"pruner {self.name!r} needs {', '.join(missing)}")
        scores = np.asarray(self.fn(scene, ctx), dtype=np.float64)
        if scores.shape != (len(scene),):
            raise PrunerOutputError("method", f"pruner {self.name!r} returned shape {scores.shape}, "
                                              f"expected ({len(scene)},)")
        bad = ~np.isfinite(scores)
        if bad.any():
            raise PrunerOutputError("method", f"pruner {self.name!r} returned {int(bad.sum())} non-finite "
                                              f"scores (first: splat {int(np.flatnonzero(bad)[0])})")
        return scores


class PrunerOutputError(HarnessError, RuntimeError):
    """Scores that break the pruner contract (a wrong shape, NaN or inf): one line naming the pruner,
    never used to select splats. A RuntimeError too, as it was before it named the pruner."""


PRUNERS: Registry[PrunerSpec] = Registry("pruner", modules=BUILTIN_MODULES, group=ENTRY_POINT_GROUP)


def register_pruner(name: str, *, params: type[Params] = NoParams, needs=(), label: str | None = None,
                    group: str = "other", ablation: Ablation | None = None, summary: str | None = None,
                    uses_cameras: Callable[[Params], bool] | None = None,
                    budget_note: Callable[[Params], str | None] | None = None, uses_device: bool = False):
    """Decorator registering ``fn(scene, ctx) -> scores`` under ``name`` with its metadata.

    ``summary`` defaults to the first line of the function's docstring, ``label`` to ``name``.
    """
    bad = set(needs) - KNOWN_NEEDS
    if bad:
        raise ValueError(f"unknown needs {sorted(bad)}; known: {sorted(KNOWN_NEEDS)}")
    if group not in GROUPS:
        raise ValueError(f"unknown group {group!r}; known: {', '.join(GROUPS)}")
    if not (isinstance(params, type) and issubclass(params, Params)):
        raise TypeError(f"pruner {name!r}: params must be a Params dataclass, got {params!r}")

    def deco(fn):
        doc = (fn.__doc__ or "").strip().splitlines()
        spec = PrunerSpec(name=name, fn=fn, params=params, needs=frozenset(needs), label=label or name,
                          group=group, ablation=ablation, summary=summary or (doc[0] if doc else name),
                          uses_cameras=uses_cameras or (lambda p: False),
                          budget_note=budget_note or (lambda p: None), uses_device=bool(uses_device))
        PRUNERS.add(name, spec, same=lambda old, new: old.fn.__qualname__ == new.fn.__qualname__
                    and old.fn.__module__ == new.fn.__module__)
        return fn

    return deco


def get_pruner(name: str) -> PrunerSpec:
    return PRUNERS.get(name)


def list_pruners() -> list[PrunerSpec]:
    """Every registered pruner, built-ins first, in registration order."""
    return list(PRUNERS)


def ablation_grid() -> dict[tuple[bool, bool], PrunerSpec]:
    """(descriptors, beta) -> the pruner in that cell of the paper's ablation grid."""
    return {(s.ablation.descriptors, s.ablation.beta): s for s in PRUNERS if s.ablation is not None}


def proposed() -> PrunerSpec | None:
    """The paper's method: the full cell of the ablation grid."""
    return ablation_grid().get((True, True))
