"""LPIPS-VGG behaviour with the converted weights: identity, monotonicity, agreement with the package."""

import numpy as np
import pytest
import torch
from skimage import data, filters

from harness.core.errors import InputError
from harness.metrics import lpips_weights as lw
from harness.metrics.lpips_vgg import LpipsVGG, load_features, save_features
from tests.optional_support import require_lpips_package

pytestmark = pytest.mark.weights

BLUR_SIGMAS = (0.5, 1.0, 2.0, 4.0)
NOISE_SIGMAS = (0.02, 0.05, 0.1, 0.2)


@pytest.fixture(scope="module")
def model():
    if not lw.weights_available():
        pytest.skip("LPIPS-VGG weights not converted here: run harness fetch --weights")
    return LpipsVGG(device="cpu")


@pytest.fixture(scope="module")
def astronaut():
    return data.astronaut().astype(np.float32) / 255.0


@pytest.fixture(scope="module")
def astronaut_features(model, astronaut):
    return model.features(astronaut)


def test_identical_is_zero(model, astronaut, astronaut_features):
    assert model.distance(astronaut_features, astronaut) == 0.0


def test_grows_with_blur(model, astronaut, astronaut_features):
    blurred = [filters.gaussian(astronaut, sigma=s, channel_axis=-1) for s in BLUR_SIGMAS]
    values = model.distances(astronaut_features, blurred)
    assert values[0] > 0.005 and np.all(np.diff(values) > 0), values


def test_grows_with_noise(model, astronaut, astronaut_features):
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(astronaut.shape).astype(np.float32)
    noisy = [np.clip(astronaut + s * noise, 0, 1) for s in NOISE_SIGMAS]
    values = model.distances(astronaut_features, noisy)
    assert values[0] > 0.005 and np.all(np.diff(values) > 0), values


def test_cached_distance_equals_the_lpips_package_forward(model):
    """Independent truth: lpips.LPIPS.forward (two passes, 1x1 lin convs, NCHW) with the same trunk."""
    require_lpips_package()
    ref_module = lw.new_lpips_module(pretrained_lin=True)
    ref_module.net.load_state_dict(lw.load_backbone()["net"])
    rng = np.random.default_rng(3)
    a = data.chelsea()[:96, :128].astype(np.float32) / 255
    b = np.clip(a + rng.normal(0, 0.05, a.shape), 0, 1).astype(np.float32)
    with torch.no_grad():
        expected = ref_module(torch.from_numpy(a).permute(2, 0, 1)[None], torch.from_numpy(b).permute(2, 0, 1)[None],
                              normalize=True).item()
    assert model(a, b) == pytest.approx(expected, abs=1e-6)
    assert model(b, a) == pytest.approx(expected, abs=1e-6)
    batch = model.distances(model.features(a), [b, a, b])
    assert batch == pytest.approx([expected, 0.0, expected], abs=1e-6)


def test_features_save_load_round_trip(model, tmp_path):
    a = data.coffee()[:64, :80].astype(np.float32) / 255
    b = a[::-1].copy()
    feats = model.features(a)
    path = save_features(feats, tmp_path / "f.pt")
    again = load_features(path)
    assert again.size == feats.size and all(torch.equal(x, y) for x, y in zip(again.layers, feats.layers))
    assert model.distance(again, b) == model.distance(feats, b)


def test_bad_images(model):
    a = np.zeros((32, 40, 3), np.float32)
    feats = model.features(a)
    with pytest.raises(InputError, match="differs from the reference"):
        model.distance(feats, np.zeros((32, 41, 3), np.float32))
    with pytest.raises(InputError, match="too small"):
        model.features(np.zeros((15, 40, 3), np.float32))
    bad = a.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(InputError, match="NaN"):
        model.distance(feats, bad)


class _PackageLpips(LpipsVGG):
    """LpipsVGG computed by the lpips package's own modules (torchvision VGG16 randomly initialised,
    then loaded with the same converted weights; the package's ScalingLayer and v0.1 linear layers):
    what LpipsVGG ran before it built its trunk itself."""

    def __init__(self):
        super().__init__(device="cpu")
        module = lw.new_lpips_module(pretrained_lin=True)
        module.net.load_state_dict(lw.load_backbone()["net"], strict=True)
        self._package_scale = module.scaling_layer
        self._trunk = module.net.to(memory_format=torch.channels_last).eval()
        self._lin = [lin.model[-1].weight.detach().reshape(-1) for lin in module.lins]

    def _to_input(self, images):
        x = torch.from_numpy(np.stack(images)).permute(0, 3, 1, 2)
        x = self._package_scale(x.clamp(0.0, 1.0) * 2.0 - 1.0)
        return x.contiguous(memory_format=torch.channels_last)


def test_trunk_built_from_weights_is_bit_identical_to_the_package_modules(model):
    require_lpips_package()
    package = _PackageLpips()
    rng = np.random.default_rng(5)
    a = data.astronaut()[100:196, 150:278].astype(np.float32) / 255
    images = [np.clip(a + rng.normal(0, s, a.shape), 0, 1).astype(np.float32) for s in (0.01, 0.1)]
    images.append(rng.random((48, 80, 3), dtype=np.float32))
    for img in images:
        ours, theirs = model.features(img), package.features(img)
        assert all(torch.equal(x, y) for x, y in zip(ours.layers, theirs.layers))
    feats = model.features(a)
    assert np.array_equal(model.distances(feats, images[:2]), package.distances(feats, images[:2]))
    assert model(images[2], images[2][::-1].copy()) == package(images[2], images[2][::-1].copy())


def test_scoring_imports_neither_torchvision_nor_lpips():
    import subprocess
    import sys

    script = ("import sys, numpy as np\nfrom harness.metrics.lpips_vgg import LpipsVGG\n"
              "m = LpipsVGG(device='cpu')\nm(np.zeros((32, 32, 3), np.float32), np.ones((32, 32, 3), np.float32))\n"
              "print(sorted(k for k in ('torchvision', 'lpips') if k in sys.modules))")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]"


@pytest.mark.parametrize("shape", [(64, 48), (100, 130)])
def test_a_pair_in_step_is_the_cached_distance_bit_for_bit(model, shape):
    """``model(a, b)`` runs both images through the trunk slice by slice and differences each layer
    in place (a third less memory for 1024x768): the value is that of features(a) then distance(b),
    which test_cached_distance_equals_the_lpips_package_forward checks against the package."""
    rng = np.random.default_rng(shape[0])
    a = rng.random((*shape, 3)).astype(np.float32)
    b = np.clip(a + rng.normal(0, 0.05, a.shape), 0, 1).astype(np.float32)
    assert model(a, b) == model.distance(model.features(a), b) > 0
    assert model(b, a) == model.distance(model.features(b), a)
    assert model(a, a) == 0.0
