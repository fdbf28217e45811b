"""compare_images and MetricSuite: per-view reference caching gives the same numbers as pairwise scoring."""

import math

import numpy as np
import pytest
from skimage import data

from harness.core.errors import InputError
from harness.metrics import lpips_weights as lw
from harness.metrics.lpips_vgg import LpipsVGG
from harness.metrics.psnr import psnr
from harness.metrics.ssim import ssim
from harness.metrics.suite import MetricSuite, compare_images

pytestmark = pytest.mark.weights


@pytest.fixture(scope="module")
def model():
    if not lw.weights_available():
        pytest.skip("LPIPS-VGG weights not converted here: run harness fetch --weights")
    return LpipsVGG(device="cpu")


def _views():
    rng = np.random.default_rng(0)
    refs = {"v0": data.astronaut()[:48, :64].astype(np.float32) / 255,
            "v1": data.chelsea()[:48, :64].astype(np.float32) / 255}
    pruned = {k: [np.clip(r + rng.normal(0, s, r.shape), 0, 1).astype(np.float32) for s in (0.02, 0.08)]
              for k, r in refs.items()}
    return refs, pruned


def test_compare_images_identical(model):
    a = data.astronaut()[:32, :32].astype(np.float32) / 255
    out = compare_images(a, a, lpips_model=model, yuv=True)
    assert out["psnr"] == math.inf and out["ssim"] == 1.0 and out["lpips"] == 0.0 and out["psnr_yuv"] == math.inf


def test_compare_images_building_its_model_alongside_gives_the_same_values(model):
    """Without a model the network is built while PSNR/SSIM run on a worker thread: same keys, same bits."""
    refs, pruned = _views()
    a, b = refs["v0"], pruned["v0"][1]
    given = compare_images(a, b, lpips_model=model, yuv=True)
    for device in (None, "cpu"):
        built = compare_images(a, b, yuv=True, device=device)
        assert list(built) == list(given) and built == given
    assert compare_images(a, b, names=("psnr", "ssim")) == {k: given[k] for k in ("psnr", "ssim")}


def test_alongside_runs_both_and_raises_either_error():
    import threading

    from harness.metrics.suite import _alongside

    names = _alongside(lambda: threading.current_thread().name, lambda: threading.current_thread().name)
    assert names[0] != names[1] and names[1] == threading.main_thread().name

    def fail(message):
        raise ValueError(message)

    finished = []
    with pytest.raises(ValueError, match="background"):
        _alongside(lambda: fail("background"), lambda: finished.append("front"))
    assert finished == ["front"]
    with pytest.raises(ValueError, match="front"):
        _alongside(lambda: finished.append("back"), lambda: fail("front"))


def test_suite_matches_pairwise_scores_and_evicts_to_disk(model, tmp_path):
    refs, pruned = _views()
    suite = MetricSuite(model, feature_dir=tmp_path, max_in_memory=1)
    for key, ref in refs.items():
        suite.reference(key, ref)
    assert suite.has_reference("v0") and not suite.has_reference("v2")
    for key in ("v0", "v1", "v0"):  # v0 was evicted from memory: reloaded from disk
        rows = suite.score_many(key, pruned[key])
        for img, row in zip(pruned[key], rows):
            assert row["psnr"] == pytest.approx(psnr(refs[key], img), abs=1e-12)
            assert row["ssim"] == pytest.approx(ssim(refs[key], img), abs=1e-12)
            assert row["lpips"] == pytest.approx(model(refs[key], img), abs=1e-6)
        assert rows[0]["lpips"] < rows[1]["lpips"]
    assert len(list(tmp_path.glob("*.lpips.pt"))) == 2 and not list(tmp_path.glob("*.part*"))


def test_suite_errors(model):
    refs, pruned = _views()
    suite = MetricSuite(model)
    with pytest.raises(KeyError, match="no reference"):
        suite.score("v0", pruned["v0"][0])
    suite.reference("v0", refs["v0"])
    with pytest.raises(InputError, match="sizes differ"):
        suite.score("v0", refs["v0"][:-2])
    assert suite.score("v0", refs["v0"])["psnr"] == math.inf
