"""ConfSplatPrune: Confident Splatting's Beta confidence, learned post hoc (see :mod:`.train`).

Defaults are their code's (``amirhossein-razlighi/Confident-Splatting``), with the saliency rank loss
of the version contemporary with the paper (``e801512``, 2025-07-06: margin 1.0 from step 0); HEAD
(``e7343b2``) uses margin 0.10 from step 1000, which a post-hoc run of 600 steps would never reach —
``rank_margin=0.1`` (with ``rank_start_step`` scaled to the run) is that variant. ``iterations`` (600)
is the harness's budget for a frozen-geometry, post-hoc run (theirs: 30k joint training steps); no
wall-clock budget cuts it short unless ``time_budget_s`` is set (then the run is a lower bound and
the iterations done are logged and returned by :func:`.train.optimise_confidence`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from harness.core.params import Params, param
from methods.registry import PruneContext, register_pruner


@dataclass(frozen=True)
class ConfSplatParams(Params):
    train_longest_side: int = param(128, ge=0, doc="long side (px) of the training views it renders; 0 = as given")
    iterations: int = param(600, ge=0, doc="optimisation steps, one training view each (post-hoc budget; "
                            "theirs: 30k joint training steps)")
    time_budget_s: float | None = param(None, gt=0, doc="stop earlier when the optimisation loop exceeds this "
                                        "(s; none = never: a binding budget makes the result a lower bound)")
    lr: float = param(1e-3, gt=0, doc="Adam learning rate of the Beta parameters (theirs: 1e-3)")
    init: float = param(1.0, doc="initial raw Beta parameters a, b (theirs: 1, i.e. c = 0.5)")
    lambda_dssim: float = param(0.2, ge=0, le=1, doc="weight λ of (1 − SSIM) against L1")
    lambda_sparsity: float = param(2e-3, ge=0, doc="weight of the mean confidence (sparsity)")
    lambda_entropy: float = param(2e-3, ge=0, doc="weight of the mean Beta entropy")
    entropy_sign: Literal["minimize", "maximize"] = param("minimize", doc="their beta_entropy_sign")
    rank_weight: float = param(1.0, ge=0, doc="weight of the saliency rank loss (theirs: 1.0; 0 = off)")
    rank_interval: int = param(25, ge=1, doc="steps between rank-loss steps (theirs: 25)")
    rank_pairs: int = param(2048, ge=1, doc="most- vs least-salient pairs per rank step (theirs: 2048)")
    rank_margin: float = param(1.0, ge=0, doc="hinge margin m of relu(m + c_lo − c_hi) (2025 code e801512: "
                               "1.0, always active; HEAD e7343b2: 0.10)")
    rank_start_step: int = param(0, ge=0, doc="first rank-loss step (2025 code: 0; HEAD: 1000 of 30k joint steps, "
                                 "i.e. after warm-up, which a post-hoc run on a trained scene is past)")
    early_stop: bool = param(False, doc="graphdeco's early termination in the training renders")
    threads: int = param(1, ge=0, doc="torch intra-op threads of the set-up (0 = unchanged); the optimisation "
                         "runs on one thread, so the scores do not depend on it")


def _budget(p: ConfSplatParams) -> str | None:
    """Fewer steps than its own default: its numbers are a lower bound of what ConfSplat reaches."""
    default = ConfSplatParams().iterations
    return f"lower bound ({p.iterations} iterations)" if p.iterations < default else None


@register_pruner("confsplat", params=ConfSplatParams, needs=("cameras",), label="ConfSplatPrune",
                 group="camera-aware", budget_note=_budget, uses_device=True)
def confsplat_score(scene, ctx: PruneContext) -> np.ndarray:
    """Confident Splatting Beta confidence α/(α+β), learned with frozen geometry to match the unpruned render."""
    from methods.confsplat.train import optimise_confidence

    if len(scene) == 0:  # nothing to learn a confidence for (the renders have no splats to weigh)
        return np.zeros(0, np.float64)
    return optimise_confidence(scene, ctx.cameras, ctx.params, seed=ctx.seed, device=ctx.device).confidence
