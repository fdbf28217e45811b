"""ConfSplatPrune: Confident Splatting's Beta confidence, learned post hoc (see :mod:`.train`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from harness.core.params import Params, param
from methods.registry import PruneContext, register_pruner


@dataclass(frozen=True)
class ConfSplatParams(Params):
    train_longest_side: int = param(128, ge=0, doc="long side (px) of the training views it renders; 0 = as given")
    iterations: int = param(600, ge=0, doc="optimisation steps, one training view each")
    time_budget_s: float = param(300.0, gt=0, doc="stop earlier when the optimisation loop exceeds this (s)")
    lr: float = param(1e-3, gt=0, doc="Adam learning rate of the Beta parameters (theirs: 1e-3)")
    init: float = param(1.0, doc="initial raw Beta parameters a, b (theirs: 1, i.e. c = 0.5)")
    lambda_dssim: float = param(0.2, ge=0, le=1, doc="weight λ of (1 − SSIM) against L1")
    lambda_sparsity: float = param(2e-3, ge=0, doc="weight of the mean confidence (sparsity)")
    lambda_entropy: float = param(2e-3, ge=0, doc="weight of the mean Beta entropy")
    entropy_sign: Literal["minimize", "maximize"] = param("minimize", doc="their beta_entropy_sign")
    early_stop: bool = param(False, doc="graphdeco's early termination in the training renders")
    threads: int = param(1, ge=0, doc="torch intra-op threads while scoring (0 = unchanged)")


@register_pruner("confsplat", params=ConfSplatParams, needs=("cameras",), label="ConfSplatPrune",
                 group="camera-aware")
def confsplat_score(scene, ctx: PruneContext) -> np.ndarray:
    """Confident Splatting Beta confidence α/(α+β), learned with frozen geometry to match the unpruned render."""
    from methods.confsplat.train import optimise_confidence

    return optimise_confidence(scene, ctx.cameras, ctx.params, seed=ctx.seed, device=ctx.device).confidence
