"""BetaDescPrune (the paper) and its three ablations, registered as pruners.

* ``betadesc``: HSFH neighbourhood descriptors at voxel level (voxel = fraction of the bounding-
  box diagonal), statistics s, ℓ, u interpolated to the splats with weight w, per-splat opacity o,
  Eq. 4 evidence → Beta(A, B) retention posterior → score (default μ + γσ, μ = A/(A+B), the
  erratum reading; ``score="literal"`` gives the paper's literal B/(A+B) + γσ).
* ``betadesc-nodesc``: the same Beta model and the same reading without neighbourhood descriptors:
  the s, ℓ, u slots of Eq. 4 are filled from each splat's own parameters (the paper's "individual
  splat parameters"; :mod:`.nodesc`, ``nodesc_def``: ``splat-params`` = anisotropy, colour/SH
  dispersion and extent, or ``param-stats`` = v1's, anisotropy for both ℓ and u), w = 1. With
  ``nodesc_def="opacity-only"`` the s, ℓ, u terms are dropped and the score is a monotone function
  of opacity: it ranks exactly like the ``opacity`` baseline (its twin, not an ablation).
* ``betadesc-nobeta``: the same descriptor statistics and evidence, ranked deterministically by
  the net evidence A − B (no posterior mean, no σ: evidence magnitude is not turned into
  confidence and uncertainty earns no bonus).
* ``betadesc-nodesc-nobeta``: the no-descriptor statistics ranked by A − B.

Every variant takes the reading parameters of :mod:`.params` (``reading`` bundle: default,
paper-literal, v1) with the same defaults. Camera-agnostic: when the context holds cameras (and
``view_weight`` > 0) the edge proxy of :mod:`.view_aware` adds retention evidence; otherwise it is off.
"""

from __future__ import annotations

from methods.betadesc.params import (
    BetaDescParams,
    EvidenceOnlyParams,
    NoBetaParams,
    NoDescParams,
)
from methods.registry import Ablation, PruneContext, register_pruner


def _run(scene, ctx: PruneContext, *, descriptors: bool, beta: bool):
    from methods.betadesc import (
        pipeline,  # numba kernels: loaded when a betadesc variant runs
    )

    return pipeline.run(scene, ctx.params, ctx.cameras, descriptors=descriptors, beta=beta)


def _views_on(params) -> bool:
    return params.view_weight > 0


@register_pruner("betadesc", params=BetaDescParams, label="BetaDescPrune", group="ours",
                 ablation=Ablation(descriptors=True, beta=True), uses_cameras=_views_on)
def betadesc(scene, ctx: PruneContext):
    """BetaDescPrune: HSFH descriptor statistics → Beta evidence → retention confidence μ + γσ."""
    return _run(scene, ctx, descriptors=True, beta=True)


@register_pruner("betadesc-nobeta", params=NoBetaParams, label="BetaDesc (no Beta)", group="ablation",
                 ablation=Ablation(descriptors=True, beta=False), uses_cameras=_views_on)
def betadesc_nobeta(scene, ctx: PruneContext):
    """Ablation: HSFH descriptor statistics ranked by net evidence A − B (no posterior, no σ)."""
    return _run(scene, ctx, descriptors=True, beta=False)


@register_pruner("betadesc-nodesc", params=NoDescParams, label="BetaDesc (no desc.)", group="ablation",
                 ablation=Ablation(descriptors=False, beta=True), uses_cameras=_views_on)
def betadesc_nodesc(scene, ctx: PruneContext):
    """Ablation: per-splat parameter statistics (no neighbourhood descriptors), Beta score."""
    return _run(scene, ctx, descriptors=False, beta=True)


@register_pruner("betadesc-nodesc-nobeta", params=EvidenceOnlyParams, label="BetaDesc (neither)",
                 group="ablation", ablation=Ablation(descriptors=False, beta=False), uses_cameras=_views_on)
def betadesc_nodesc_nobeta(scene, ctx: PruneContext):
    """Ablation: per-splat parameter statistics ranked by net evidence A − B."""
    return _run(scene, ctx, descriptors=False, beta=False)
