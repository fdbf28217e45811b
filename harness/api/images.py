"""Images from Python: :func:`render` views of a scene, :func:`compare` two images.

``harness render`` and ``harness compare`` are these functions plus their files and printing.
Images are ``(H, W, 3)`` arrays: the renderers return float32 linear colour, unclamped; the metrics
take float arrays nominally in [0, 1] (clamped), uint8 arrays, or image files (PNG, ``.npy``).
"""

from __future__ import annotations

from pathlib import Path

from harness.core.errors import InputError

DEFAULT_METRICS = ("psnr", "ssim", "lpips")


def check_background(value) -> tuple[float, float, float]:
    """Three numbers R, G, B in [0, 1] (a sequence, or text ``"R,G,B"``)."""
    import math

    text = value if isinstance(value, str) else None
    try:
        vals = tuple(float(v) for v in (value.split(",") if text is not None else value))
    except (TypeError, ValueError):
        vals = ()
    if len(vals) != 3 or not all(math.isfinite(v) and 0.0 <= v <= 1.0 for v in vals):
        raise InputError("background", f"expected three numbers R,G,B in [0, 1], got {value!r}")
    return vals


def start_renderer(backend: str = "gl", device: str | None = None):
    """A started renderer (``.render(scene, camera, background)``, ``.close()``): ``gl`` (moderngl/EGL)
    or ``reference`` (torch, on ``device``). Errors name ``backend`` or ``device``."""
    from harness.core.devices import check_device
    from renderers import get_renderer

    check_device(device, "device")
    try:
        return get_renderer(backend, device)
    except Exception as err:  # noqa: BLE001  unknown name, no EGL/CUDA here: usage, not a crash
        raise InputError("backend", f"cannot start the {backend!r} renderer: {err}") from None


def camera_list(cameras) -> list:
    """A list of :class:`harness.core.cameras.Camera` from one camera, a list of them, or a camera
    file (cameras.json, transforms.json, COLMAP, a PLY with camera comments)."""
    from harness.core.cameras import Camera

    if isinstance(cameras, (str, Path)):
        from harness.io.cameras import load_cameras

        return load_cameras(cameras)
    cams = [cameras] if isinstance(cameras, Camera) else list(cameras or ())
    if not cams or not all(isinstance(c, Camera) for c in cams):
        raise InputError("cameras", "expected a camera file or a non-empty list of harness.core.cameras.Camera")
    return cams


def render(scene, cameras, *, backend: str = "gl", device: str | None = None, background=(0.0, 0.0, 0.0)) -> list:
    """One float32 ``(H, W, 3)`` image per camera (linear colour, unclamped: what the renderer
    returns, as ``harness render --format npy`` writes). ``scene``: a scene, a path or a name."""
    from harness.api.scenes import _scene
    from harness.core.extent import check_extent

    bg = check_background(background)
    cams = camera_list(cameras)
    scene = _scene(scene)
    check_extent(scene, scene.meta.source or "scene")
    renderer = start_renderer(backend, device)
    try:
        return [renderer.render(scene, cam, background=bg) for cam in cams]
    finally:
        renderer.close()


def metric_names(metrics, qmiv: bool = False) -> tuple[str, ...]:
    """Metric names from metric and family names (a comma-separated string or a sequence:
    ``"mpeg"``, ``("psnr", "lpips")``); with ``qmiv`` the MPEG names become their QMIV-mode twins."""
    from harness.core.suggest import did_you_mean
    from harness.metrics.registry import METRICS, expand, requestable

    words = [w.strip() for w in (metrics.split(",") if isinstance(metrics, str) else metrics) if str(w).strip()]
    known = requestable()
    bad = [str(w) for w in words if w not in known]
    if bad or not words:
        named = ", ".join(f"'{w}'{did_you_mean(w, known)}" for w in bad) or repr(metrics)
        raise InputError("metrics", f"unknown metric or family {named}; known: {', '.join(known)}")
    names = expand(words)
    if qmiv:
        qm = {m.name for m in METRICS if m.family == "mpeg-qmiv"}
        names = tuple(dict.fromkeys(n + "_qmiv" if n + "_qmiv" in qm else n for n in names))
    return names


#: peak bytes per pixel of ``compare`` by the metrics asked (RSS over the image size, measured on
#: 1024x768 and 2048x1536 PNG pairs: PSNR 97, SSIM 322, LPIPS-VGG 1,456, the MPEG set 357), rounded
#: up; a metric not listed (a plugin's) is costed as SSIM
BYTES_PER_PIXEL = {"psnr": 120, "ssim": 400, "lpips": 1500}
MAX_COMPARE_BYTES = 4 << 30


def memory_limit() -> int:
    """compare's memory budget: :data:`MAX_COMPARE_BYTES`, or ``HARNESS_MAX_COMPARE_BYTES``."""
    import os

    text = os.environ.get("HARNESS_MAX_COMPARE_BYTES")
    if not text:
        return MAX_COMPARE_BYTES
    try:
        return int(text)
    except ValueError:
        raise InputError("HARNESS_MAX_COMPARE_BYTES", f"expected a number of bytes, got {text!r}") from None


def _bytes_per_pixel(name: str) -> int:
    """``lpips`` by itself, SSIM-like (``ssim``, ``yuv_ssim_om`` ...) and PSNR-like names by family."""
    kind = "lpips" if name == "lpips" else "ssim" if "ssim" in name else "psnr" if "psnr" in name else "ssim"
    return BYTES_PER_PIXEL[kind]


def check_memory(path, names, budget: int | None = None) -> None:
    """Refuse, from its header and before decoding, an image whose comparison by ``names`` would
    need more than the budget: ``pixels × max(bytes per pixel of each metric)`` (a PSNR-like metric
    120, SSIM-like 400, LPIPS 1,500; two 8192x8192 images need ~8 GB for PSNR alone)."""
    from harness.core.cameras import MAX_SIDE
    from harness.metrics.images import header_size

    size = header_size(path)
    if size is None or max(size) > MAX_SIDE:  # reading it says what is wrong
        return
    metric = max(names, key=_bytes_per_pixel)
    cost = _bytes_per_pixel
    need, budget = size[0] * size[1] * cost(metric), memory_limit() if budget is None else budget
    if need > budget:
        raise InputError(path, f"{size[0]}x{size[1]} images need about {need / 2**30:.1f} GiB to compare by "
                               f"{metric} (~{cost(metric)} bytes per pixel), more than compare's "
                               f"{budget / 2**30:.1f} GiB limit (at most {budget // cost(metric):,} pixels; "
                               "HARNESS_MAX_COMPARE_BYTES raises it)")


def _image(value, which: str):
    """(the image, what errors call it): a file is read (named by its path), an array kept."""
    from harness.metrics.images import read_image

    if isinstance(value, (str, Path)):
        return read_image(value), str(value)
    return value, which


def compare(a, b, metrics=DEFAULT_METRICS, *, device: str | None = None, yuv: bool = False, qmiv: bool = False,
            mask=None) -> dict:
    """The metrics of image ``b`` against the reference ``a`` (``harness compare A B``): PSNR, SSIM
    (3DGS conventions), LPIPS-VGG, or the MPEG set (``metrics="mpeg"``: as mpeg-gsc-metrics, on 8-bit
    images; ``qmiv`` its QMIV mode, same keys plus ``mode``; ``mask`` an occupancy image for the OM
    metrics, non-zero = occupied, adding ``occupancy`` in %). ``yuv`` adds float BT.709 Y/U/V PSNRs.
    An infinite PSNR (identical images) is ``inf``. Only LPIPS and SSIM run on torch (``device``).
    Image files too large to compare within the memory budget are refused before they are decoded
    (:func:`check_memory`)."""
    import numpy as np

    from harness.core.devices import check_device
    from harness.metrics.images import as_image, check_same_size
    from harness.metrics.suite import compare_images

    names = metric_names(metrics, qmiv)
    for value in (a, b):
        if isinstance(value, (str, Path)):
            check_memory(value, names)
    (a, name_a), (b, name_b) = _image(a, "first image"), _image(b, "second image")
    check_same_size(np.asarray(a), np.asarray(b), name_a, name_b)
    occupied = None
    if mask is not None:
        m, name_m = _image(mask, "mask")
        m = np.asarray(m)
        check_same_size(np.asarray(a), m, name_a, name_m)
        occupied = m if m.dtype == bool and m.ndim == 2 else np.any(as_image(m, name_m) != 0, axis=2)
    check_device(device, "device")
    values = compare_images(a, b, yuv=yuv, names=names, mask=occupied, device=device)
    if qmiv:  # same keys in both modes; the mode is said once
        values = {k[:-5] if k.endswith("_qmiv") else k: v for k, v in values.items()}
        values["mode"] = "qmiv"
    if occupied is None:
        values.pop("occupancy", None)
    return values
