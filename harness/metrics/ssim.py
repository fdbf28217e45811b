"""SSIM with the 3DGS convention, vectorised in torch (batched, GPU when present).

For each colour channel separately, with g the normalised 11x11 Gaussian window (sigma = 1.5) and *
correlation with **zero padding** of 5 px ("same" output size)::

    mu_x = g*x,  s_xx = g*(x x) - mu_x^2,  s_xy = g*(x y) - mu_x mu_y   (population, not sample, moments)
    SSIM = (2 mu_x mu_y + C1)(2 s_xy + C2) / ((mu_x^2 + mu_y^2 + C1)(s_xx + s_yy + C2)),
    C1 = (0.01 L)^2, C2 = (0.03 L)^2, L = 1 (data range; images clamped to [0, 1]).

**The metric** (``border="zero"``, the default) is the mean of that map over *all* pixels and channels,
as the graphdeco-inria 3DGS ``ssim()`` (``conv2d(padding=window_size // 2)``) does and hence as 3DGS
pruning papers report. ``border="valid"`` averages only the pixels whose window lies inside the image
(5 px border dropped); inside that region the padding never enters, so it equals scikit-image's
``structural_similarity(gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1,
channel_axis=-1)`` (which filters with reflection and then crops the same border). The two conventions
differ by the border's contribution: +5e-3 to +6e-3 on the 512x512 astronaut degraded by blur or
noise (the zero padding both images share makes border windows partly identical, so they score
higher), more on smaller images.

The separable Gaussian runs over all planes at once (numpy on CPU, bit for bit scipy's
``correlate1d``; ``conv2d`` on GPU); float64 by default so the E[x^2] - mu^2 cancellation stays far
below 1e-5. On the CPU the images
are numpy arrays and torch is not imported (``harness compare --metrics ssim``); on another device
they are torch tensors. The arithmetic is the same elementwise float64 in both, so the CPU values
are the bits the torch form gave there.
"""

from __future__ import annotations

import numpy as np

from harness.metrics.images import as_image, check_same_size

WINDOW = 11
SIGMA = 1.5
K1, K2 = 0.01, 0.03


def gaussian_taps(window: int = WINDOW, sigma: float = SIGMA) -> np.ndarray:
    """Normalised 1-D Gaussian taps exp(-(i - r)^2 / (2 sigma^2)) / Z, i = 0..window-1."""
    r = window // 2
    g = np.exp(-((np.arange(window) - r) ** 2) / (2.0 * sigma * sigma))
    return g / g.sum()


def _lib(x):
    """numpy for a numpy array, else torch."""
    if isinstance(x, np.ndarray):
        return np
    import torch

    return torch


def blur_numpy(x, taps: np.ndarray):
    """Separable zero-padded 'same' correlation of CPU ``x`` (..., H, W) with ``taps`` on both axes
    (a numpy array, or a CPU tensor: the result is of the same kind): ``scipy.ndimage.correlate1d``
    along W then H, bit for bit (:func:`harness.core.correlate.correlate_symmetric`, in numpy)."""
    from harness.core.correlate import correlate_symmetric

    out = correlate_symmetric(correlate_symmetric(np.asarray(x), taps, axis=-1), taps, axis=-2)
    return out if isinstance(x, np.ndarray) else _lib(x).from_numpy(out)


def blur_torch(x, taps: np.ndarray):
    """Same as :func:`blur_numpy` with two 1-D ``conv2d`` passes (any device)."""
    import torch

    h, w = x.shape[-2:]
    r = len(taps) // 2
    k = torch.as_tensor(taps, dtype=x.dtype, device=x.device)
    planes = x.reshape(-1, 1, h, w)
    planes = torch.nn.functional.conv2d(planes, k.view(1, 1, 1, -1), padding=(0, r))
    planes = torch.nn.functional.conv2d(planes, k.view(1, 1, -1, 1), padding=(r, 0))
    return planes.reshape(x.shape)


def _blur(x, taps: np.ndarray):
    # numpy is several times faster than torch's float64 conv2d on CPU; conv2d serves GPUs
    return blur_numpy(x, taps) if isinstance(x, np.ndarray) or x.device.type == "cpu" else blur_torch(x, taps)


def moments(x, blur=None):
    """``g*x`` and ``g*(x x)`` of batched images, stacked: the first image's side of :func:`ssim_map`
    (a reference scored against many images needs them once)."""
    return (blur or _blur)(_lib(x).stack([x, x * x]), gaussian_taps())


def ssim_map(x, y, data_range: float = 1.0, blur=None, x_moments=None):
    """Per-pixel SSIM of batched images ``(B, C, H, W)`` (zero-padded 'same' map, same shape).

    ``blur`` overrides the Gaussian implementation (:func:`blur_numpy` / :func:`blur_torch`);
    ``x_moments`` are :func:`moments` of ``x`` when already computed (the blur filters every plane on
    its own, so they are the values a joint filtering gives).
    """
    taps = gaussian_taps()
    c1, c2 = (K1 * data_range) ** 2, (K2 * data_range) ** 2
    (mu_x, e_xx) = x_moments if x_moments is not None else moments(x, blur)
    mu_y, e_yy, e_xy = (blur or _blur)(_lib(y).stack([y, y * y, x * y]), taps)
    mu_xy = mu_x * mu_y
    mu_xx, mu_yy = mu_x * mu_x, mu_y * mu_y
    num = (2 * mu_xy + c1) * (2 * (e_xy - mu_xy) + c2)
    den = (mu_xx + mu_yy + c1) * ((e_xx - mu_xx) + (e_yy - mu_yy) + c2)
    return num / den


class SsimReference:
    """The first image's side of :func:`ssim_batch` (its array and :func:`moments`), computed once
    for a reference scored against many images: ``ssim_batch(ref, b)`` with ``ref`` one of these.
    ``blur``: the Gaussian used for it and for every image scored against it (default: numpy on
    the CPU, ``conv2d`` elsewhere; :func:`blur_torch` is the torch form on any device, and makes the
    arrays torch tensors on the CPU too)."""

    def __init__(self, a, *, device=None, dtype=None, blur=None):
        self.device = _device(device, blur)
        self.blur = blur
        self.x = _tensor(a, self.device, dtype)
        with _inference(self.x):
            self.moments = moments(self.x, blur)


def _device(device, blur=None):
    """``"cpu"`` (numpy arrays) or a torch device: the one named, else :func:`default_device`;
    the torch form of the blur asks for torch on the CPU too."""
    from harness.core.devices import default_device

    name = str(device) if device is not None else default_device()
    if name == "cpu" and blur is not blur_torch:
        return "cpu"
    import torch

    return torch.device(name)


def _inference(x):
    import contextlib

    return contextlib.nullcontext() if isinstance(x, np.ndarray) else _lib(x).inference_mode()


def _tensor(a, device, dtype):
    """Images ``(B, H, W, 3)`` as ``(B, 3, H, W)`` float64 (or ``dtype``) clamped to [0, 1]: a numpy
    array for ``device == "cpu"``, else a tensor on ``device``."""
    if device == "cpu":
        a = a.cpu().numpy() if not isinstance(a, np.ndarray) and hasattr(a, "cpu") else np.asarray(a)
        return np.clip(a.astype(dtype or np.float64), 0, 1).transpose(0, 3, 1, 2)
    import torch

    a = a if isinstance(a, torch.Tensor) else np.asarray(a)
    return torch.as_tensor(a, device=device).to(dtype or torch.float64).clamp(0, 1).permute(0, 3, 1, 2)


def ssim_batch(a, b, *, border: str = "zero", device=None, dtype=None) -> np.ndarray:
    """SSIM of image pairs: ``a``, ``b`` arrays ``(B, H, W, 3)`` (or tensors) -> float64 ``(B,)``;
    ``a`` may be an :class:`SsimReference` (its device, dtype and blur win)."""
    if border not in ("zero", "valid"):
        raise ValueError(f"border must be 'zero' or 'valid', not {border!r}")
    ref = a if isinstance(a, SsimReference) else None
    device = ref.device if ref is not None else _device(device)
    x = ref.x if ref is not None else _tensor(a, device, dtype)
    y = _tensor(b, device, x.dtype)
    with _inference(x):
        s = ssim_map(x, y, blur=ref.blur if ref is not None else None,
                     x_moments=ref.moments if ref is not None else None)
        if border == "valid":
            r = WINDOW // 2
            if min(s.shape[-2:]) <= 2 * r:
                raise ValueError(f"border='valid' needs images larger than {2 * r} px per side")
            s = s[..., r:-r, r:-r]
        # on the CPU the mean in numpy: torch splits a CPU reduction over its threads, so the last digit
        # would depend on the thread count (1 vs 2 workers of a run); numpy's summation order is fixed.
        # A GPU's reduction order is fixed for a shape, and reading back one number per image is the point
        if isinstance(s, np.ndarray):
            return s.astype(np.float64).reshape(len(s), -1).mean(axis=1)
        if s.device.type != "cpu":
            return s.reshape(len(s), -1).mean(1).cpu().numpy().astype(np.float64)
        return s.cpu().numpy().astype(np.float64).reshape(len(s), -1).mean(axis=1)


def ssim(a, b, *, border: str = "zero", device=None) -> float:
    """SSIM of two images ``(H, W, 3)`` in [0, 1] (clamped), 3DGS convention unless ``border='valid'``."""
    a, b = as_image(a, "first image"), as_image(b, "second image")
    check_same_size(a, b)
    return float(ssim_batch(a[None], b[None], border=border, device=device)[0])
