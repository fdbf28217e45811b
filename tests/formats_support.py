"""Shared by the tests/test_formats_*.py modules: the fixtures' source scene, splat matching, errors.

The fixtures in ``tests/fixtures/formats`` were written by independent tools (``regenerate.sh``)
from ``grape_1k.ply``: 1,000 splats of grape_small whose centres are ≥ 4 mm apart. Decoded splats
are matched to their source by nearest centre (every format here quantises positions to < 0.2 mm),
which also covers writers that reorder (Morton, buckets) or drop (alpha byte 0) splats.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from functools import cache
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from harness.core.errors import InputError
from harness.core.scene import SH_C0, GaussianScene, normalized_quats, sigmoid
from harness.io.ply import read_ply

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "formats"
MATCH_DISTANCE = 1e-3  # far below the 4 mm spacing of the source splats


@cache
def source(sh0: bool = False) -> GaussianScene:
    scene = read_ply(FIXTURES / "grape_1k.ply")
    return scene.with_sh_degree(0) if sh0 else scene


def source_for(name: str) -> GaussianScene:
    return source(sh0=name.startswith("grape_1k_sh0."))


def match(decoded: GaussianScene, src: GaussianScene) -> np.ndarray:
    """Index of each decoded splat's source splat (nearest centre; unique; within MATCH_DISTANCE)."""
    dist, index = cKDTree(src.means.astype(np.float64)).query(decoded.means.astype(np.float64))
    assert dist.max(initial=0) < MATCH_DISTANCE, f"a decoded splat is {dist.max():.2e} from every source splat"
    assert len(np.unique(index)) == len(index), "two decoded splats matched the same source splat"
    return index


def alpha(scene: GaussianScene) -> np.ndarray:
    return sigmoid(scene.opacity_logit.astype(np.float64))


def unit_quats(scene: GaussianScene) -> np.ndarray:
    return normalized_quats(scene.quats.astype(np.float64))


def quat_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-splat max component difference of unit quaternions, sign-invariant (q ≡ −q)."""
    return np.minimum(np.abs(a - b).max(1), np.abs(a + b).max(1))


def colour(sh_dc: np.ndarray) -> np.ndarray:
    return 0.5 + SH_C0 * sh_dc.astype(np.float64)


def assert_within(name: str, error: np.ndarray, bound, errors: dict) -> None:
    """Record ``max(error)`` under ``name`` and assert every ``error <= bound`` (broadcast)."""
    error = np.asarray(error, np.float64)
    errors[name] = float(error.max(initial=0.0))
    bound = np.broadcast_to(bound, error.shape)
    over = error > bound
    assert not over.any(), (f"{name}: {int(over.sum())} values exceed the bound; "
                            f"worst {error[over].max():.3e} vs bound {bound[over].max():.3e}")


def info_line(capsys, path, *args) -> tuple[int, str, str]:
    """``harness info PATH`` in-process: (exit status, stdout, stderr)."""
    from harness.cli import main

    rc = main(["info", str(path), *args])
    out, err = capsys.readouterr()
    return rc, out, err


def assert_clean_error(capsys, path, *phrases) -> str:
    """``harness info`` fails with one ``harness: PATH: ...`` line, exit 2, no traceback."""
    rc, out, err = info_line(capsys, path)
    lines = err.strip().splitlines()
    assert rc == InputError.exit_status and out == "" and len(lines) == 1, (rc, out, err)
    assert lines[0].startswith(f"harness: {path}: ") and "Traceback" not in err, lines[0]
    for phrase in phrases:
        assert phrase in lines[0], (phrase, lines[0])
    return lines[0]


def splat_transform() -> list[str] | None:
    """Command prefix running PlayCanvas splat-transform, or None when it is not installed.

    ``HARNESS_SPLAT_TRANSFORM`` names its ``bin/cli.mjs`` (run with node) or an executable; else a
    ``splat-transform`` on PATH is used.
    """
    given = os.environ.get("HARNESS_SPLAT_TRANSFORM")
    if given and Path(given).is_file():
        return ["node", given] if given.endswith((".js", ".mjs")) and shutil.which("node") else [given]
    found = shutil.which("splat-transform")
    return [found] if found else None


def run_splat_transform(args: list[str]) -> None:
    cmd = splat_transform()
    assert cmd is not None
    subprocess.run([*cmd, "-q", "-w", *args], check=True, capture_output=True, timeout=120)
