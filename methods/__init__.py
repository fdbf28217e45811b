"""Pruners: each scores every splat of a scene (higher = keep). See :mod:`methods.registry`."""

from methods.registry import (
    PruneContext,
    PrunerSpec,
    get_pruner,
    list_pruners,
    register_pruner,
)
from methods.targeting import PruneSelection, select_by_keep, select_by_ratio

__all__ = [
    "PruneContext",
    "PrunerSpec",
    "PruneSelection",
    "get_pruner",
    "list_pruners",
    "register_pruner",
    "select_by_keep",
    "select_by_ratio",
]
