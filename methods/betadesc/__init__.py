"""BetaDescPrune (the paper) and its three ablations, registered as pruners.

* ``betadesc``: HSFH neighbourhood descriptors at voxel level (voxel = fraction of the bounding-
  box diagonal), statistics s, ℓ, u interpolated to the splats with weight w, per-splat opacity o,
  Eq. 6 evidence → Beta(A, B) retention posterior → score (default μ + γσ, μ = A/(A+B), the
  erratum reading; ``score="literal"`` gives the paper's literal B/(A+B) + γσ).
* ``betadesc-nodesc``: the same Beta model, but s, ℓ, u come from each splat's own parameters
  (log-scale anisotropy for ℓ = 1 − u, colour/SH dispersion for s; see :mod:`.statistics`), w = 1 — no
  neighbourhood, no voxels, no FPFH.
* ``betadesc-nobeta``: the same descriptor statistics and evidence, ranked deterministically by
  the net evidence A − B (no posterior mean, no σ: evidence magnitude is not turned into
  confidence and uncertainty earns no bonus).
* ``betadesc-nodesc-nobeta``: per-splat statistics ranked by A − B.

Camera-agnostic: when the context holds cameras (and ``view_weight`` > 0) the edge proxy of
:mod:`.view_aware` adds retention evidence; otherwise it is off.
"""

from __future__ import annotations

from methods.betadesc import pipeline
from methods.registry import PruneContext, register_pruner

_DESCRIPTOR_PARAMS = {"voxel": 0.01, "radius_voxels": 5.0, "max_nn": 100, "colour_bins": 8}
_EVIDENCE_PARAMS = {"preset": "baseline", "view_weight": 0.25}
_BETA_PARAMS = {"prior": 1.0, "score": "ucb", "gamma": 0.25, "z": 1.0, "q": 0.1}


@register_pruner("betadesc", params={**_DESCRIPTOR_PARAMS, **_EVIDENCE_PARAMS, **_BETA_PARAMS})
def betadesc(scene, ctx: PruneContext):
    """BetaDescPrune: HSFH descriptor statistics → Beta evidence → retention confidence μ + γσ."""
    return pipeline.run(scene, ctx.params, ctx.cameras, descriptors=True, beta=True)


@register_pruner("betadesc-nodesc", params={**_EVIDENCE_PARAMS, **_BETA_PARAMS})
def betadesc_nodesc(scene, ctx: PruneContext):
    """Ablation: per-splat parameter statistics (no neighbourhood descriptors), Beta score."""
    return pipeline.run(scene, ctx.params, ctx.cameras, descriptors=False, beta=True)


@register_pruner("betadesc-nobeta", params={**_DESCRIPTOR_PARAMS, **_EVIDENCE_PARAMS})
def betadesc_nobeta(scene, ctx: PruneContext):
    """Ablation: HSFH descriptor statistics ranked by net evidence A − B (no posterior, no σ)."""
    return pipeline.run(scene, ctx.params, ctx.cameras, descriptors=True, beta=False)


@register_pruner("betadesc-nodesc-nobeta", params=dict(_EVIDENCE_PARAMS))
def betadesc_nodesc_nobeta(scene, ctx: PruneContext):
    """Ablation: per-splat parameter statistics ranked by net evidence A − B."""
    return pipeline.run(scene, ctx.params, ctx.cameras, descriptors=False, beta=False)
