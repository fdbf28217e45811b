"""Where the harness keeps downloaded data, converted weights and its stage cache.

``HARNESS_CACHE`` overrides the root (default ``~/.cache/harness``); it survives fresh clones,
so the README's set-up command is a no-op the second time. ``HARNESS_SHARED_DATA`` overrides the
folder of the project's shared scenes (default ``../shared/data`` beside the repository).
"""

from __future__ import annotations

import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]


def cache_dir() -> Path:
    """Root of the harness cache (created on demand)."""
    root = Path(os.environ.get("HARNESS_CACHE", Path.home() / ".cache" / "harness")).expanduser()
    root.mkdir(parents=True, exist_ok=True)
    return root


def data_dir() -> Path:
    """Fetched scenes: ``<cache>/data``."""
    d = cache_dir() / "data"
    d.mkdir(parents=True, exist_ok=True)
    return d


def weights_dir() -> Path:
    """Converted network weights: ``<cache>/weights``."""
    d = cache_dir() / "weights"
    d.mkdir(parents=True, exist_ok=True)
    return d


def shared_data_dir() -> Path:
    """The project's shared real scenes (may not exist: tests then skip with a reason)."""
    return Path(os.environ.get("HARNESS_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))


def results_dir() -> Path:
    return REPO_ROOT / "results"
