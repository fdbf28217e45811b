"""Schema checks of stage-cache entries: what a well-formed value of each stage must satisfy.

Each ``*_check(...)`` returns a function ``value -> problem | None`` for
:meth:`harness.run.cache.StageCache.get_json` / ``get_array`` (``check=``). The checksum of an
entry proves that its bytes are those written; these checks prove that what was written makes
sense for the inputs it is keyed on, so a damaged or hand-edited entry — or one written by a bug —
is discarded and recomputed instead of used:

* **load**: ``n_splats`` a non-negative integer, ``sh_degree`` 0..3.
* **views**: a rig name, lists of cameras that each pass :func:`harness.core.cameras.camera_problem`
  (size within the maximum render size, finite intrinsics, a rigid pose), at least one test view.
* **score** record: ``n`` equal to the scene's splat count, ``seconds`` finite and ≥ 0;
  score array: one dimension, length = the splat count, no NaN.
* **prune** record: ``splats_out = N − round(r·N)`` (:func:`methods.targeting.removal_count`),
  hence ≤ N; ``mask`` a sha256; ``tau_quantile`` in [0, 1]; mask array: ``ceil(N/8)`` packed bytes
  whose set bits count ``splats_out``, padding bits zero, and whose digest is the mask key.
* **render_ref** record: ``width``/``height`` those of the camera; array: floats ``(H, W, 3|4)``
  (colour, or colour + alpha), finite.
* **metrics**: every requested metric present; PSNR (and any ``psnr*`` variant) a number in
  [0, +inf] (+inf: identical renders, the only non-finite value allowed), SSIM finite in [−1, 1],
  LPIPS finite and ≥ 0, any other metric finite; timings finite and ≥ 0.
"""

from __future__ import annotations

import math
import re

import numpy as np

_SHA = re.compile(r"^[0-9a-f]{64}$")


def _real(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _seconds(rec: dict, *names) -> str | None:
    for n in names:
        v = rec.get(n)
        if v is not None and not (_real(v) and math.isfinite(v) and v >= 0):
            return f"{n} {v!r} is not a finite non-negative time"
    return None


def _mapping(v) -> str | None:
    return None if isinstance(v, dict) else f"expected an object, got {type(v).__name__}"


def load_check():
    def check(rec):
        if (why := _mapping(rec)) is not None:
            return why
        n, sh = rec.get("n_splats"), rec.get("sh_degree")
        if not (isinstance(n, int) and not isinstance(n, bool) and n >= 0):
            return f"n_splats {n!r} is not a splat count"
        if sh not in (0, 1, 2, 3):
            return f"sh_degree {sh!r} is not 0..3"
        for k in ("ply_base", "ply_row"):  # the pruned .ply's size model (harness.io.plysize)
            v = rec.get(k)
            if v is not None and not (isinstance(v, int) and not isinstance(v, bool) and v > 0):
                return f"{k} {v!r} is not a byte count"
        for k in ("largest_coordinate", "blur"):  # harness.core.extent
            v = rec.get(k)
            if v is not None and not (isinstance(v, (int, float)) and not isinstance(v, bool) and v >= 0):
                return f"{k} {v!r} is not a distance or share"
        return None
    return check


def views_check():
    from harness.core.cameras import Camera, camera_problem

    def check(rec):
        if (why := _mapping(rec)) is not None:
            return why
        if not isinstance(rec.get("rig"), str):
            return "rig is not a name"
        for split in ("train", "test"):
            cams = rec.get(split)
            if not isinstance(cams, list):
                return f"{split} is not a list of cameras"
            for i, d in enumerate(cams):
                why = camera_problem(Camera.from_dict(d))
                if why:
                    return f"{split} camera {i}: {why}"
        if not rec["test"]:
            return "no test views"
        return None
    return check


def score_record_check(n: int):
    def check(rec):
        if (why := _mapping(rec)) is not None:
            return why
        if rec.get("n") != n:
            return f"records {rec.get('n')!r} scores for a {n}-splat scene"
        return _seconds(rec, "seconds")
    return check


def score_array_check(n: int):
    def check(arr):
        arr = np.asarray(arr)
        if arr.ndim != 1 or len(arr) != n:
            return f"score array of shape {arr.shape} for a {n}-splat scene"
        if arr.dtype.kind not in "fiu":
            return f"score array of type {arr.dtype}"
        if arr.dtype.kind == "f" and np.isnan(arr).any():
            return f"{int(np.isnan(arr).sum())} NaN scores"
        return None
    return check


def prune_check(n: int, ratio: float):
    from methods.targeting import removal_count

    expected = n - removal_count(n, ratio)

    def check(rec):
        if (why := _mapping(rec)) is not None:
            return why
        out = rec.get("splats_out")
        if out != expected or isinstance(out, bool):
            return f"splats_out {out!r}, expected {expected} (N = {n}, ratio {ratio:g})"
        if not isinstance(rec.get("mask"), str) or not _SHA.match(rec["mask"]):
            return "mask is not a digest"
        q = rec.get("tau_quantile")
        if not (_real(q) and 0.0 <= q <= 1.0):
            return f"tau_quantile {q!r} is outside [0, 1]"
        tau = rec.get("tau")
        if tau is not None and not (_real(tau) and not math.isnan(tau)):
            return f"tau {tau!r} is not a number"
        return _seconds(rec, "seconds")
    return check


def mask_check(n: int, kept: int | None = None, digest: str | None = None):
    def check(packed):
        packed = np.asarray(packed)
        if packed.dtype != np.uint8 or packed.ndim != 1 or len(packed) != (n + 7) // 8:
            return f"packed mask of shape {packed.shape} / {packed.dtype} for a {n}-splat scene"
        keep = np.unpackbits(packed)
        if keep[n:].any():
            return "padding bits set beyond the splat count"
        if kept is not None and int(keep[:n].sum()) != kept:
            return f"mask keeps {int(keep[:n].sum())} splats, its prune record says {kept}"
        if digest is not None:
            from harness.run.cache import digest_mask

            if digest_mask(keep[:n].astype(bool)) != digest:
                return "mask content does not match its key"
        return None
    return check


def render_ref_record_check(width: int, height: int):
    def check(rec):
        if (why := _mapping(rec)) is not None:
            return why
        if rec.get("width") != width or rec.get("height") != height:
            return f"records a {rec.get('width')}x{rec.get('height')} render of a {width}x{height} camera"
        return _seconds(rec, "seconds")
    return check


def image_check(width: int, height: int):
    def check(img):
        img = np.asarray(img)
        if img.ndim != 3 or img.shape[:2] != (height, width) or img.shape[2] not in (1, 3, 4) \
                or img.dtype.kind != "f":
            return f"render of shape {img.shape} / {img.dtype}, expected ({height}, {width}, 3|4) floats"
        if not np.isfinite(img).all():
            return "render holds NaN/inf pixels"
        return None
    return check


def alpha_check(width: int, height: int):
    """An accumulated-opacity image (H, W) with values in [0, 1]."""
    def check(img):
        img = np.asarray(img)
        if img.shape != (height, width) or img.dtype.kind != "f":
            return f"alpha of shape {img.shape} / {img.dtype}, expected ({height}, {width}) floats"
        if not (np.isfinite(img).all() and img.min(initial=0.0) >= -1e-6 and img.max(initial=0.0) <= 1.0 + 1e-6):
            return "alpha outside [0, 1] or not finite"
        return None
    return check


def _metric_problem(rec: dict, names) -> str | None:
    """Why the values ``names`` of a metrics record are unusable: numbers, each within its metric's
    registered ``valid_range`` (+inf only for a metric registered ``inf_if_identical``, PSNR's
    identical images; :mod:`harness.metrics.registry`)."""
    from harness.metrics.registry import METRICS

    for k in names:
        v = rec.get(k)
        if not _real(v) or math.isnan(v):
            return f"{k} {v!r} is not a number"
        problem = METRICS.get(k).problem(v)
        if problem:
            return problem
    return None


def gt_check(names):
    """A ``gt`` entry: the unpruned render's photo metrics ``names``."""
    names = tuple(names)

    def check(rec):
        return _mapping(rec) or _metric_problem(rec, names) or _seconds(rec, "seconds")
    return check


def metrics_check(names):
    names = tuple(names)

    def check(rec):
        return _mapping(rec) or _metric_problem(rec, names) or _seconds(rec, "render_s", "metrics_s", "ref_features_s")
    return check
