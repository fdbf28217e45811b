"""The contract every registered pruner keeps, checked on each one the registry lists (built-ins and
plugins alike, so a new pruner is covered without touching this file; not the suite's own fakes).

``score(scene, ctx)`` returns one float64 per splat (shape (N,), finite) — also for N = 0 and N = 1;
the same seed gives the same scores; and scores follow the splats, not their order: scoring the
scene with its splats permuted gives the permuted scores (to 1e-5 relative: float32 training sums in
another order),
except for a pruner registered as drawing its scores at random per position (``random``: its
scores are i.i.d. draws, equivariant in distribution only). Camera-aware pruners get a small rig
(3 training views at 32 px). A training budget (a parameter named ``iterations``) is cut to 20
steps: the contract is about what comes back, not about how well it was trained.
"""

from __future__ import annotations

import numpy as np
import pytest

from harness.views.rigs import make_rig
from methods.registry import PruneContext, list_pruners
from tests.scene_factory import random_scene

N = 48


def _pruners() -> list:
    """Every pruner a user can run: built-ins and installed plugins (not the test suite's own fakes,
    some broken on purpose, registered by other test modules)."""
    return [s for s in list_pruners() if not s.fn.__module__.split(".")[0].startswith("test")]


#: pruners whose score of a splat is a random draw per position (equivariant in distribution only)
DRAWN_PER_POSITION = {"random"}


def _params(spec):
    budget = {"iterations": 20} if "iterations" in spec.params.names() else {}
    return spec.parse_params(budget)


@pytest.fixture(scope="module")
def scene():
    return random_scene(N, sh_degree=1, seed=3)


@pytest.fixture(scope="module")
def cameras(scene):
    return list(make_rig("auto", scene, n_train=3, n_test=1, longest_side=32).train)


def _score(spec, scene, cameras, seed=0) -> np.ndarray:
    params = _params(spec)
    ctx = PruneContext(params=params, seed=seed, cameras=cameras if spec.wants_cameras(params) else None)
    return spec.fn(scene, ctx)


def _check(out, n: int, name: str) -> np.ndarray:
    assert isinstance(out, np.ndarray), f"{name} returned {type(out).__name__}, not a numpy array"
    assert out.dtype == np.float64 and out.shape == (n,), f"{name}: {out.dtype} {out.shape}, expected float64 ({n},)"
    assert np.isfinite(out).all(), f"{name}: non-finite scores"
    return out


@pytest.mark.parametrize("spec", _pruners(), ids=lambda s: s.name)
def test_shape_dtype_and_finiteness(spec, scene, cameras):
    _check(_score(spec, scene, cameras), N, spec.name)


@pytest.mark.parametrize("spec", _pruners(), ids=lambda s: s.name)
@pytest.mark.parametrize("n", [0, 1])
def test_empty_and_single_splat_scenes(spec, scene, cameras, n):
    _check(_score(spec, scene.subset(np.arange(N) < n), cameras), n, f"{spec.name} on {n} splat(s)")


@pytest.mark.parametrize("spec", _pruners(), ids=lambda s: s.name)
def test_same_seed_same_scores(spec, scene, cameras):
    assert np.array_equal(_score(spec, scene, cameras, seed=7), _score(spec, scene, cameras, seed=7))


@pytest.mark.parametrize("spec", _pruners(), ids=lambda s: s.name)
def test_scores_follow_the_splats_not_their_order(spec, scene, cameras):
    if spec.name in DRAWN_PER_POSITION:
        pytest.skip(f"{spec.name} draws a score per position: equivariant in distribution only")
    perm = np.random.default_rng(11).permutation(N)
    base, permuted = _score(spec, scene, cameras), _score(spec, scene.subset(perm), cameras)
    np.testing.assert_allclose(permuted, base[perm], rtol=1e-5, atol=1e-7, err_msg=spec.name)
