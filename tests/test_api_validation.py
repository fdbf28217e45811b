"""The Python API holds what it is given to the command line's rules: one ``validate()`` for every
scene (shapes, dtypes, finite values, rotations), typed arguments (a bool is not a ratio, a float is
not a seed), every failure a HarnessError naming the argument."""

from __future__ import annotations

import numpy as np
import pytest

import harness
from harness.core.arguments import number, whole
from harness.core.errors import InputError
from harness.core.validate import validate
from tests.scene_factory import random_scene


def _broken(change):
    s = random_scene(200, 1, seed=3)
    change(s)
    return s


@pytest.mark.parametrize("change, phrase", [
    (lambda s: s.opacity_logit.__setitem__(slice(0, 10), np.nan), "10 of 200 splats have NaN/inf values (first: row 0, "
                                                                   "opacity_logit)"),
    (lambda s: s.opacity_logit.__setitem__(slice(None), np.nan), "200 of 200 splats"),
    (lambda s: s.sh_rest.__setitem__((5, 1, 2), np.inf), "first: row 5, sh_rest"),
    (lambda s: setattr(s, "opacity_logit", s.opacity_logit[:100]), "opacity_logit has shape (100,), expected (200,)"),
    (lambda s: setattr(s, "means", s.means.astype(np.float64)), "means is float64; a scene holds float32"),
    (lambda s: setattr(s, "quats", s.quats.tolist()), "quats is a list, not a numpy array"),
    (lambda s: s.quats.__setitem__(3, 0.0), "1 splats have a zero-norm rotation quaternion (first: row 3)"),
    (lambda s: s.extra.__setitem__("nx", np.zeros(3, np.float32)), "extra property 'nx' must be an array of 200 rows"),
])
def test_a_scene_changed_in_memory_is_validated_by_every_call(tmp_path, change, phrase):
    s = _broken(change)
    with pytest.raises(InputError, match="scene: ") as info:
        validate(s)
    assert phrase in str(info.value)
    for call in (lambda: harness.prune(s, 0.3, method="opacity"), lambda: harness.score(s, "opacity"),
                 lambda: harness.save(s, tmp_path / "x.ply"), lambda: harness.info(s), lambda: harness.cameras(s)):
        with pytest.raises(harness.HarnessError, match="scene: "):
            call()
    assert not (tmp_path / "x.ply").exists()


def test_info_can_drop_what_validation_refuses():
    s = _broken(lambda s: s.opacity_logit.__setitem__(slice(0, 10), np.nan))
    got = harness.info(s, drop_nonfinite=True)
    assert got["splats"] == 190 and got["dropped_nonfinite"] == 10


@pytest.mark.parametrize("call, phrase", [
    (lambda s: harness.prune(s, True, method="opacity"), "ratio: must be a number in [0, 1], got True (bool)"),
    (lambda s: harness.prune(s, keep="0.5", method="opacity"), "keep: must be a number in [0, 1], got '0.5' (str)"),
    (lambda s: harness.prune(s, 0.3, method="random", seed=1.5), "seed: must be a whole number >= 0, got 1.5"),
    (lambda s: harness.prune(s, 0.3, method="random", seed=True), "seed: must be a whole number >= 0, got True"),
    (lambda s: harness.score(s, "random", seed=-5), "seed: must be a whole number >= 0, got -5"),
    (lambda s: harness.cameras(s, seed=-5), "seed: must be a whole number >= 0, got -5"),
    (lambda s: harness.cameras(s, longest_side="256"), "longest_side: must be a whole number from 1 to 8192, got '25"),
    (lambda s: harness.cameras(s, longest_side=1.5), "longest_side: must be a whole number from 1 to 8192, got 1.5"),
    (lambda s: harness.cameras(s, n_test=2.5), "n_test: must be a whole number from 1 to 1000, got 2.5"),
    (lambda s: harness.cameras(s, n_train=-1), "n_train: must be a whole number from 0 to 1000, got -1"),
    (lambda s: harness.cameras(s, aspect=True), "aspect: must be a number in [0.1, 10], got True"),
    (lambda s: harness.cameras(s.subset(np.zeros(len(s), bool))), "scene: has no splats"),
    (lambda s: harness.evaluate({"name": "x"}, workers=1.5), "workers: must be a whole number from 1 to 256"),
    (lambda s: harness.evaluate({"name": "x"}, threads=0), "threads: must be a whole number from 1 to 1024"),
])
def test_arguments_of_the_wrong_type_are_one_error_naming_them(call, phrase):
    with pytest.raises(harness.HarnessError) as info:
        call(random_scene(200, 0, seed=1))
    assert phrase in str(info.value)


def test_whole_and_number_take_numpy_and_refuse_the_rest():
    assert whole(np.int64(3), "n", 1) == 3 and number(np.float32(0.5), "r", 0, 1) == 0.5 and number(1, "r") == 1.0
    for bad in (True, 1.0, "1", None, np.bool_(True)):
        with pytest.raises(InputError, match="n: must be a whole number"):
            whole(bad, "n")
    for bad in (False, "0.5", float("nan"), float("inf"), 2):
        with pytest.raises(InputError, match=r"r: must be a number in \[0, 1\]"):
            number(bad, "r", 0, 1)


def test_a_pruner_that_returns_nan_is_named_not_used():
    import dataclasses

    from methods import PruneContext, get_pruner

    bad = dataclasses.replace(get_pruner("opacity"), fn=lambda scene, ctx: np.full(len(scene), np.nan))
    with pytest.raises(harness.HarnessError, match="method: pruner 'opacity' returned 200 non-finite scores"):
        bad.score(random_scene(200, 0, seed=1), PruneContext(params={}))
    with pytest.raises(RuntimeError):  # what callers caught before it named the pruner
        bad.score(random_scene(200, 0, seed=1), PruneContext(params={}))
