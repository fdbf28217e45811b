"""Skip a test, with the reason, when an optional package it compares with is not installed.

The lpips package (and the torchvision it builds on) is the independent truth some LPIPS tests
compare with; scoring never imports it, so a machine without it (a GPU machine running the project
from source) still runs every other test.
"""

from __future__ import annotations

import importlib

import pytest


def require_package(*names: str, why: str) -> None:
    """Skip the calling test unless every module of ``names`` imports (``why``: what it is needed for)."""
    for name in names:
        try:
            importlib.import_module(name)
        except ImportError as err:
            pytest.skip(f"the {name} package is not installed ({err.__class__.__name__}): {why}")


def require_lpips_package() -> None:
    require_package("lpips", "torchvision", why="the lpips package's own modules are this test's reference")
