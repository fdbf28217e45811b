"""Image metrics used by the field: PSNR, SSIM (3DGS convention), LPIPS v0.1 VGG, and MPEG's
mpeg-gsc-metrics set (:mod:`.mpeg`: RGB-/YUV-PSNR, YUV-SSIM and their occupancy-masked variants,
RGB-/YUV-IV-SSIM).

* :func:`compare_images` scores one pair.
* :class:`MetricSuite` scores many images of the same view against that view's reference, computing
  the reference's LPIPS features once (kept in memory, least recently used views evicted, and
  optionally on disk so an evicted view is reloaded instead of recomputed), and its side of SSIM and
  of the MPEG set (8-bit/YUV planes, SSIM window moments) once (:func:`reference_sides`).

Every function takes float images ``(H, W, 3)`` nominally in [0, 1] and clamps them to [0, 1]
(the MPEG metrics quantise them to 8 bit as the tool does). Conventions are documented in
:mod:`.psnr`, :mod:`.ssim`, :mod:`.lpips_vgg`, :mod:`.mpeg`. The OM metrics need occupancy: pass each
render's alpha (``reference(..., alpha=)``, ``score(..., alpha=)``); the mask is the union of both
renders' occupancy (:func:`.mpeg.occupancy_mask`); without alphas it is all ones (the tool's
maskless overload: OM = full frame).

**Against a photo** (the ``gt_`` metrics, :func:`.registry.gt_names`): a view registered with its
captured photo (``reference(..., photo=)``) also scores every image against the photo — each
metric of the suite as ``gt_<name>``, plus ``gt_psnr_om`` — and :meth:`MetricSuite.photo_scores`
scores the reference (the unpruned render) itself. The OM mask of every photo metric of a view is
the region the *unpruned* splats cover (the photo has no alpha), the same for the unpruned and
every pruned render of the view, so their values pair: pixels where the reference's accumulated
alpha is at least :data:`GT_OCCUPANCY_ALPHA` = 0.5, i.e. where the render shows mostly splats rather
than the (black) background the splats do not hold. Not the tool's 10/255: on a cropped scene that
rule also takes in faint haze over the missing background (bonsai-7k-mini, first held-out view at
390 px: 50 % of the frame at 10/255, 33 % at 0.5, 31 % at 0.99; OM-PSNR against the photo 13.6 /
18.6 / 19.3 dB). ``gt_occupancy`` is that region's share of the frame (%). An image's LPIPS trunk
pass is shared by its two comparisons.
"""

from __future__ import annotations

import hashlib
import os
from collections import OrderedDict
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from harness.core.errors import InputError
from harness.metrics import registry as _registry
from harness.metrics.images import as_image, check_same_size, read_image
from harness.metrics.pairs import pair_values, reference_sides
from harness.metrics.psnr import mse, psnr, psnr_from_mse, summarize_psnr, yuv_psnr

if TYPE_CHECKING:  # served lazily by __getattr__ (they import torch)
    from harness.metrics.lpips_vgg import LpipsFeatures, LpipsVGG, load_features, save_features
    from harness.metrics.ssim import ssim

# LPIPS and SSIM run on torch (1-2 CPU-s to import): imported where they are computed, so that
# PSNR and the MPEG set alone (`harness compare --metrics psnr`) never import it
_LAZY = {"LpipsFeatures": "lpips_vgg", "LpipsVGG": "lpips_vgg", "load_features": "lpips_vgg",
         "save_features": "lpips_vgg", "ssim": "ssim", "ssim_batch": "ssim"}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f"harness.metrics.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = [
    "METRICS",
    "LpipsFeatures",
    "LpipsVGG",
    "MetricSuite",
    "compare_images",
    "default_lpips",
    "load_features",
    "psnr",
    "read_image",
    "save_features",
    "ssim",
    "summarize_psnr",
    "yuv_psnr",
]


@lru_cache(maxsize=1)
def default_lpips() -> LpipsVGG:
    """One shared :class:`LpipsVGG` (default device, float32) per process."""
    from harness.metrics.lpips_vgg import LpipsVGG

    return LpipsVGG()


#: what a suite measures between two renders (the ``gt_`` twins come with a view's photo)
METRICS = tuple(m.name for m in _registry.METRICS if not _registry.is_gt(m.name))
#: LPIPS is computed from features (a view's reference features once, an image's trunk pass shared
#: by its comparisons with the reference and the photo), not pair by pair
LPIPS = "lpips"
#: the photo metrics' OM region: where the unpruned render's accumulated alpha reaches this (module docstring)
GT_OCCUPANCY_ALPHA = 0.5


def checked(values: dict, where: str) -> dict:
    """``values`` when every registered metric among them has a number (finite; +inf only where the
    metric is registered ``inf_if_identical``, PSNR's identical images), else InputError naming the
    metric: a NaN from any metric — an MPEG member on a degenerate image, a plugin's — is never a
    score, a table cell or a JSON value."""
    import math

    for name, v in values.items():
        spec = _registry.spec(name)
        if spec is None or v is None or math.isfinite(v):
            continue
        why = spec.problem(float(v))
        if why:
            raise InputError(f"metric {name}", f"gave {float(v)!r} for {where}; a metric's value must be a finite "
                                               "number")
    return values


def _on_cuda(device) -> bool:
    """Does a suite on ``device`` score with the torch forms by default? On CUDA: on the CPU the
    numpy/numba forms are faster, and MPS has no float64 (torch is not imported to say so)."""
    return device is not None and str(device).split(":")[0] == "cuda"


def compare_images(a, b, *, lpips_model: LpipsVGG | None = None, yuv: bool = False,
                   names=("psnr", "ssim", "lpips"), mask=None, device=None) -> dict:
    """``{"psnr", "ssim", "lpips"}`` (plus ``psnr_y/u/v/yuv`` with ``yuv=True``) of two images, or
    the metrics ``names`` (MPEG ones with ``occupancy`` when masked; ``mask``: see :mod:`.mpeg`).

    uint8 images are scored by the MPEG metrics as they are (no float round trip). ``device``: where
    SSIM and LPIPS run when no ``lpips_model`` is given (default: :func:`default_lpips`'s device).
    Without a model, LPIPS's network is built (torch's import: 1-2 s on one core) on this thread
    while the other metrics are computed on a worker thread (numpy releases the GIL), so a one-pair
    ``compare`` pays for the slower of the two, not their sum; LPIPS itself runs after both, on all
    cores. The values are the same either way."""
    raw_a, raw_b = a, b
    a, b = as_image(a, "first image"), as_image(b, "second image")
    check_same_size(a, b)
    u8 = lambda raw, f: raw if isinstance(raw, np.ndarray) and raw.dtype == np.uint8 and raw.ndim == 3 \
        and raw.shape[2] >= 3 else f  # noqa: E731
    wants_lpips = LPIPS in names

    def others(dev) -> dict:
        out = pair_values(a, b, names, device=dev, mask=mask, raw=(u8(raw_a, a), u8(raw_b, b)))
        if yuv:
            out.update(yuv_psnr(a, b))
        return out

    if not wants_lpips:
        out = others(device)
    elif lpips_model is not None:
        out = others(lpips_model.device)
        out[LPIPS] = lpips_model(a, b)
    else:
        out, model = _alongside(lambda: others(device), lambda: _new_lpips(device))
        out[LPIPS] = model(a, b)  # after the worker: torch's threads then have every core to themselves
    return checked(out, f"these {a.shape[1]}x{a.shape[0]} images")


def _new_lpips(device) -> LpipsVGG:
    """The shared model on the default device, else a new one on ``device``."""
    if device is None:
        return default_lpips()
    from harness.metrics.lpips_vgg import LpipsVGG

    return LpipsVGG(device=device)


def _alongside(background, foreground):
    """``(background(), foreground())`` with ``background`` run on a worker thread while
    ``foreground`` runs on this one. An error of the foreground is raised as soon as the background
    has stopped (it is cancelled if it has not started); one of the background is raised after the
    foreground has finished."""
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1, thread_name_prefix="compare") as pool:
        pending = pool.submit(background)
        try:
            front = foreground()
        except BaseException:
            pending.cancel()
            raise
        return pending.result(), front


class MetricSuite:
    """Scores images against per-view references, with each reference's LPIPS features cached.

    ``suite.reference(key, image)`` registers a view's reference; ``suite.score(key, image)`` (or
    ``score_many``) then costs one LPIPS trunk pass per image. At most ``max_in_memory`` views keep
    their features in memory (about 380 MB per 1024x768 view); with ``feature_dir`` every reference is
    also written there (features + image, atomically) and reloaded when evicted. ``names`` selects
    the metrics (a subset of ``METRICS``); without "lpips" no network is loaded. A model the suite
    creates itself leaves the process's torch thread count as it found it (the runner budgets
    workers × threads ≤ cores).

    ``torch_forms`` (default: on CUDA): score each batch of ``score_many`` with the metrics' torch
    forms on the suite's device (:mod:`.batched`: the images uploaded once, each metric over the whole
    batch, the results read back once); otherwise image by image with the CPU forms. ``batch``: the
    images a caller should pass per call (:meth:`batch_size`; default: by the device's free memory).
    """

    def __init__(self, lpips_model: LpipsVGG | None = None, *, names=METRICS, device=None,
                 feature_dir: str | Path | None = None, max_in_memory: int = 4, yuv: bool = False,
                 torch_forms: bool | None = None, batch: int | None = None):
        self.names = tuple(names)
        unknown = sorted(set(self.names) - set(METRICS))
        if unknown:
            raise ValueError(f"unknown metric(s) {', '.join(unknown)}; known: {', '.join(METRICS)}")
        if LPIPS in self.names and lpips_model is None:
            import torch

            from harness.metrics.lpips_vgg import LpipsVGG

            threads = torch.get_num_threads()
            lpips_model = LpipsVGG(device=device) if device is not None else default_lpips()
            torch.set_num_threads(threads)
        self.lpips = lpips_model if LPIPS in self.names else None
        self.device = self.lpips.device if self.lpips is not None else device
        self.feature_dir = Path(feature_dir) if feature_dir is not None else None
        if self.feature_dir is not None:
            self.feature_dir.mkdir(parents=True, exist_ok=True)
        self.max_in_memory = max(1, int(max_in_memory))
        self.yuv = yuv
        self._cache: OrderedDict[str, tuple[np.ndarray, LpipsFeatures]] = OrderedDict()
        self._alpha: dict[str, np.ndarray] = {}  # reference alphas (OM metrics), evicted with _cache
        self._photo: dict[str, tuple] = {}  # view -> (photo, its LPIPS features, reference occupancy mask)
        self._photo_ref: dict[str, dict] = {}  # view -> gt_ metrics of its reference
        self._sides: dict[str, dict] = {}  # reference_sides of the views in _cache, evicted with it
        self.wants_alpha = _registry.needs_alpha(self.names)
        self.torch_forms = _on_cuda(self.device) if torch_forms is None else bool(torch_forms)
        self.batch = None if batch is None else max(1, int(batch))

    # -- photos (gt_ metrics) ------------------------------------------------------------------
    def _set_photo(self, key: str, photo, ref: np.ndarray, ref_feats, alpha) -> None:
        img = as_image(photo, f"photo of {key}")
        check_same_size(ref, img, f"reference of {key}", f"photo of {key}")
        mask = np.asarray(alpha, np.float32) >= GT_OCCUPANCY_ALPHA if alpha is not None else None
        feats = self.lpips.features(img, f"photo of {key}") if self.lpips is not None else None
        self._photo[key] = (img, feats, mask)
        self._photo_ref[key] = self._photo_values(key, ref, None if feats is None or ref_feats is None
                                                  else self.lpips.feature_distance(feats, ref_feats))

    def _photo_values(self, key: str, img: np.ndarray, lpips_value) -> dict:
        """``gt_<name>`` of ``img`` against the view's photo (module docstring)."""
        photo, _, mask = self._photo[key]
        base = [n for n in self.names if n != LPIPS]
        row = pair_values(photo, img, base, device=self.device, mask=mask)
        out = {_registry.GT_PREFIX + k: v for k, v in row.items() if k in base}
        if "psnr" in self.names:
            m = np.ones(img.shape[:2], bool) if mask is None else mask  # float64, as PSNR (and the torch form)
            out["gt_psnr_om"] = psnr_from_mse(mse(photo[m], img[m])) if m.any() else 0.0
        if lpips_value is not None:
            out["gt_lpips"] = float(lpips_value)
        out["gt_occupancy"] = 100.0 * float(mask.mean()) if mask is not None else 100.0
        return out

    def photo_scores(self, view_key: str) -> dict:
        """The ``gt_`` metrics of the view's reference (the unpruned render) against its photo."""
        return checked(dict(self._photo_ref[str(view_key)]), f"the photo of view {view_key}")

    def _stem(self, key: str) -> Path:
        return self.feature_dir / hashlib.sha256(str(key).encode()).hexdigest()[:24]

    def _remember(self, key: str, image: np.ndarray, feats: LpipsFeatures) -> None:
        self._cache[key] = (image, feats)
        self._cache.move_to_end(key)
        while len(self._cache) > self.max_in_memory:
            gone, _ = self._cache.popitem(last=False)
            self._alpha.pop(gone, None)
            self._photo.pop(gone, None)
            self._photo_ref.pop(gone, None)
            self._sides.pop(gone, None)

    def reference(self, view_key: str, image, alpha=None, photo=None) -> None:
        """Register (or replace) the reference image of ``view_key`` and cache its features
        (``alpha``: the render's (H, W) alpha, for the OM metrics' occupancy; ``photo``: the view's
        captured photo at the render's size, for the ``gt_`` metrics)."""
        key = str(view_key)
        self._alpha.pop(key, None)
        self._photo.pop(key, None)
        self._photo_ref.pop(key, None)
        self._sides.pop(key, None)
        if alpha is not None:
            self._alpha[key] = np.asarray(alpha, np.float32)
        img = as_image(image, f"reference of {key}")
        feats = self.lpips.features(img, f"reference of {key}") if self.lpips is not None else None
        if self.feature_dir is not None and feats is not None:
            stem = self._stem(key)
            part = stem.with_name(stem.name + f".part{os.getpid()}.npy")
            np.save(part, img)
            if alpha is not None:
                np.save(stem.with_suffix(".alpha.npy"), self._alpha[key])
            from harness.metrics.lpips_vgg import save_features

            save_features(feats, stem.with_suffix(".lpips.pt"))
            part.replace(stem.with_suffix(".ref.npy"))
        self._remember(key, img, feats)
        if photo is not None:
            self._set_photo(key, photo, img, feats, alpha)

    def has_reference(self, view_key: str) -> bool:
        key = str(view_key)
        return key in self._cache or (
            self.feature_dir is not None and self._stem(key).with_suffix(".ref.npy").is_file()
        )

    def _get(self, key: str) -> tuple[np.ndarray, LpipsFeatures]:
        if key in self._cache:
            self._cache.move_to_end(key)
            return self._cache[key]
        if self.feature_dir is not None:
            stem = self._stem(key)
            if stem.with_suffix(".ref.npy").is_file() and stem.with_suffix(".lpips.pt").is_file():
                img = np.load(stem.with_suffix(".ref.npy"), allow_pickle=False)
                from harness.metrics.lpips_vgg import load_features

                feats = load_features(stem.with_suffix(".lpips.pt"), self.lpips.device)
                self._remember(key, img, feats)
                if stem.with_suffix(".alpha.npy").is_file():
                    self._alpha[key] = np.load(stem.with_suffix(".alpha.npy"), allow_pickle=False)
                return img, feats
        raise KeyError(f"no reference registered for view {key!r}; call reference() first")

    def batch_size(self, height: int, width: int) -> int:
        """How many images one :meth:`score_many` call should get (1 with the CPU forms)."""
        if self.batch is not None:
            return self.batch
        if not self.torch_forms:
            return 1
        from harness.metrics.batched import batch_size

        return batch_size(height, width, self.device or "cpu")

    def score_many(self, view_key: str, images, alphas=None) -> list[dict]:
        """Metrics of each image against the reference of ``view_key`` (LPIPS batched); ``alphas``
        (one per image, or None) give the OM metrics' occupancy together with the reference's.
        Every value is a number (:func:`checked`)."""
        key = str(view_key)
        rows = self._score_on_device(key, images, alphas) if self.torch_forms else self._score_on_host(key, images,
                                                                                                      alphas)
        return [checked(row, f"image {i} of view {key}") for i, row in enumerate(rows)]

    def _score_on_host(self, key: str, images, alphas) -> list[dict]:
        """:meth:`score_many` with the CPU forms, image by image."""
        ref, feats = self._get(key)
        imgs = [as_image(im, f"image {i} of {key}") for i, im in enumerate(images)]
        for i, img in enumerate(imgs):
            check_same_size(ref, img, f"reference of {key}", f"image {i} of {key}")
        photo = self._photo.get(key)
        refs = [feats] + ([photo[1]] if photo is not None and photo[1] is not None else [])
        lp = self.lpips.distances_to(refs, imgs, f"image of {key}") if self.lpips is not None \
            else np.full((len(imgs), 2), None)
        rows = []
        ref_alpha = self._alpha.get(key)
        for i, (img, (d, *d_photo)) in enumerate(zip(imgs, lp)):
            alpha = None if alphas is None else alphas[i]
            mask = None
            if self.wants_alpha and (ref_alpha is not None or alpha is not None):
                from harness.metrics.mpeg import occupancy_mask

                mask = occupancy_mask(*(x for x in (ref_alpha, alpha) if x is not None))
            if key not in self._sides:  # also after a reload from feature_dir
                self._sides[key] = reference_sides(ref, self.names, self.device)
            row = pair_values(ref, img, self.names, device=self.device, mask=mask, sides=self._sides[key])
            if self.yuv:
                row.update(yuv_psnr(ref, img))
            if d is not None:
                row[LPIPS] = float(d)
            if photo is not None:
                row.update(self._photo_values(key, img, d_photo[0] if d_photo else None))
            rows.append(row)
        return rows

    def _score_on_device(self, key: str, images, alphas) -> list[dict]:
        """:meth:`score_many` with the torch forms, the whole batch at once (:mod:`.batched`)."""
        from harness.metrics.batched import ViewOnDevice, to_batch

        ref, feats = self._get(key)
        photo = self._photo.get(key)
        view = self._sides.get(key)
        if not isinstance(view, ViewOnDevice):  # also after a reload from feature_dir
            view = self._sides[key] = ViewOnDevice(ref, self.names, self.device, self._alpha.get(key),
                                                   *(photo[0], photo[2]) if photo is not None else ())
        x = to_batch(images, ref.shape[:2], key, self.device)
        rows = view.score(x, alphas)
        if self.lpips is not None:
            refs = [feats] + ([photo[1]] if photo is not None and photo[1] is not None else [])
            for row, (d, *d_photo) in zip(rows, self.lpips.distances_batch(refs, x)):
                row[LPIPS] = float(d)
                if d_photo:
                    row[_registry.GT_PREFIX + LPIPS] = float(d_photo[0])
        if self.yuv:
            for row, img in zip(rows, x.cpu().numpy()):
                row.update(yuv_psnr(ref, img))
        return rows

    def score(self, view_key: str, image, alpha=None) -> dict:
        """``{"psnr", "ssim", "lpips"}`` (the suite's names) of ``image`` against the reference of ``view_key``."""
        return self.score_many(view_key, [image], None if alpha is None else [alpha])[0]
