"""The generated scenes: byte-reproducible (their pinned sha256), where up went is what the test rigs
say, and the arithmetic-only logarithm they use is the logarithm."""

from __future__ import annotations

import numpy as np
import pytest

from harness.io import generated
from harness.io.datasets import SCENES, GeneratedScene, sha256_file
from harness.io.scenes import load_scene
from harness.views.rigs import SCENE_RIGS


@pytest.mark.parametrize("name", sorted(generated.GENERATORS))
def test_generated_scene_is_its_pinned_bytes(name, tmp_path):
    spec = SCENES[name]
    assert isinstance(spec, GeneratedScene) and spec.generator == name
    path = generated.generate(name, tmp_path / spec.disk_name)
    assert sha256_file(path) == spec.sha256
    scene = load_scene(path)
    assert len(scene) == spec.splats and np.all(np.isfinite(scene.means))
    norms = np.linalg.norm(scene.quats.astype(np.float64), axis=1)
    np.testing.assert_allclose(norms, 1.0, atol=1e-5)


@pytest.mark.parametrize("name", sorted(generated.GENERATORS))
def test_the_test_rigs_know_where_up_went(name):
    np.testing.assert_allclose(SCENE_RIGS[name].up, generated.up_of(name), atol=1e-4)


def test_arithmetic_log_is_the_log():
    x = np.geomspace(1e-6, 1e3, 2001)
    np.testing.assert_allclose(generated._log(x), np.log(x), rtol=0, atol=1e-13)
