"""BetaDescPrune's parameters, grouped by stage; each variant takes the groups its stages use.

* descriptors (HSFH neighbourhoods): ``voxel``, ``radius_voxels``, ``max_nn``, ``colour_bins``;
* evidence (Eq. 4 coefficients and the optional view-aware edge term): ``preset``, ``view_weight``;
* Beta posterior and score: ``prior``, ``score``, ``gamma``, ``z``, ``q``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from harness.core.params import Params, param


@dataclass(frozen=True)
class DescriptorParams(Params):
    voxel: float = param(0.01, gt=0, le=1, doc="voxel edge as a fraction of the bounding-box diagonal")
    radius_voxels: float = param(5.0, gt=0, doc="FPFH neighbourhood radius, in voxels")
    max_nn: int = param(100, ge=1, doc="most neighbours per FPFH neighbourhood")
    colour_bins: int = param(8, ge=1, le=256, doc="bins per channel of the neighbourhood colour histogram")


@dataclass(frozen=True)
class EvidenceParams(Params):
    preset: Literal["baseline", "flat", "opacity-heavy", "structure-heavy"] = param(
        "baseline", doc="evidence coefficients: baseline = the paper's; the others are this project's own")
    view_weight: float = param(0.0, ge=0, doc="weight of the optional view-aware edge evidence (needs cameras; "
                               "0 = camera-agnostic, the paper's setting)")


@dataclass(frozen=True)
class BetaParams(Params):
    prior: float = param(1.0, gt=0, doc="Beta prior A0 = B0")
    score: Literal["ucb", "lcb", "quantile", "literal"] = param(
        "ucb", doc="ranking score: ucb μ+γσ (erratum reading), lcb μ−zσ, quantile BetaInvCDF(q), literal B/(A+B)+γσ")
    gamma: float = param(0.25, ge=0, doc="uncertainty weight γ of the ucb / literal scores")
    z: float = param(1.0, ge=0, doc="σ multiple of the lcb score")
    q: float = param(0.1, gt=0, lt=1, doc="quantile of the quantile score")


@dataclass(frozen=True)
class BetaDescParams(DescriptorParams, EvidenceParams, BetaParams):
    """The full method: descriptors, evidence and the Beta score."""


@dataclass(frozen=True)
class NoDescParams(EvidenceParams, BetaParams):
    """No neighbourhood descriptors: evidence and the Beta score."""


@dataclass(frozen=True)
class NoBetaParams(DescriptorParams, EvidenceParams):
    """Descriptors and evidence, ranked by net evidence (no Beta score)."""


@dataclass(frozen=True)
class EvidenceOnlyParams(EvidenceParams):
    """Neither descriptors nor the Beta score."""
