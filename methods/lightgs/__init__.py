"""LightGSPrune: LightGaussian's global significance, pruning only (see :mod:`.significance`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.core.params import Params, param
from methods.registry import PruneContext, register_pruner


@dataclass(frozen=True)
class LightGSParams(Params):
    train_longest_side: int = param(512, ge=0, doc="long side (px) of the training views it renders; 0 = as given")
    v_pow: float = param(0.1, ge=0, doc="exponent of the volume factor (V/V_ref)^v_pow (LightGaussian: 0.1)")
    early_stop: bool = param(True, doc="graphdeco's early termination at T < 1e-4 in the count pass")
    threads: int = param(1, ge=0, doc="torch intra-op threads while scoring (0 = unchanged)")


@register_pruner("lightgs", params=LightGSParams, needs=("cameras",), label="LightGSPrune", group="camera-aware",
                 uses_device=True)
def lightgs_score(scene, ctx: PruneContext) -> np.ndarray:
    """LightGaussian global significance Σ o·T over training views × (V/V_ref)^0.1."""
    from methods.lightgs.significance import significance, volume_factor
    from renderers.pixel_pairs import torch_threads

    p = ctx.params
    with torch_threads(p.threads):
        imp = significance(scene, ctx.cameras, longest_side=p.train_longest_side, early_stop=p.early_stop,
                           device=ctx.device)
    return imp * volume_factor(scene.scales_log, p.v_pow)
