"""Work units of a run, executed in pool workers (or in-process with one worker).

Each function takes a plain, picklable task description, computes what the cache lacks, stores it
atomically, and returns a small summary (timings, errors). The planner decided what is missing. Per-process state —
the last loaded scene, the renderer (one GL context per process), the metric suite with its cached reference features
— lives in :data:`_STATE`, so consecutive tasks on the same scene or view reuse it.

The same functions run on every executor (:mod:`harness.run.executors`). An executor that holds
inputs in shared memory (Ray's object store) hands them in: ``scene=`` the loaded scene, and for a
view ``ref=`` its reference render ``(image, alpha or None)``; such arrays may be read-only, and
nothing here writes into its inputs. ``keep_ref=True`` returns the reference a view task rendered
(``out["ref_images"]``) so that it can be passed on instead of being read back from the cache.

Thread budget: :func:`init_worker` sets torch/numba/BLAS threads to ``threads`` so that
``workers × threads ≤ cores``.
"""

from __future__ import annotations

import io
import os
import time
import traceback
from dataclasses import dataclass, field

import numpy as np

from harness.core.cameras import Camera
from harness.core.errors import task_error
from harness.core.params import Params
from harness.run.cache import StageCache
from harness.run.toolkit import Toolkit
from harness.run.view_renders import ViewRenders, host_array, stacked

_STATE: dict = {}


def init_worker(threads: int, imports: tuple[str, ...] = (), preload: tuple[str, ...] = ()) -> None:
    """Pool initializer: cap threads (torch, BLAS, numba, llvmpipe), import ``preload`` modules, then
    plugin modules (they register pruners).

    ``preload`` exists for modules that must come first: importing triton *after* an EGL llvmpipe
    context was created segfaults (two LLVMs in one process); importing it first is safe.
    """
    import importlib

    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS",
                "LP_NUM_THREADS"):
        os.environ[var] = str(threads)
    for name in preload:
        try:
            importlib.import_module(name)
        except ImportError:
            pass
    try:
        import torch

        torch.set_num_threads(threads)
    except ImportError:
        pass
    for name in imports:
        importlib.import_module(name)


def _cache(root: str) -> StageCache:
    # a worker's warnings go to stderr as one line each (StageCache's default)
    c = _STATE.get("cache")
    if c is None or c.location != root:
        c = _STATE["cache"] = StageCache(root)
    return c


def _scene(toolkit: Toolkit, path: str, lod, digest: str):
    if _STATE.get("scene_digest") != digest:
        _STATE["scene"] = None  # free the previous scene before loading the next
        _STATE["scene"] = toolkit.load_scene(path, lod)
        _STATE["scene_digest"] = digest
    return _STATE["scene"]


def _renderer(toolkit: Toolkit, name: str, device: str):
    key = (toolkit.make_renderer, name, device)  # another toolkit (tests' fakes) never gets this one's renderer
    if _STATE.get("renderer_key") != key:
        old = _STATE.get("renderer")
        if old is not None:
            old.close()
        _STATE["renderer"] = toolkit.make_renderer(name, device)
        _STATE["renderer_key"] = key
    return _STATE["renderer"]


def _metrics(toolkit: Toolkit, names: tuple[str, ...], device: str):
    key = (toolkit.make_metrics, tuple(names), device)
    if _STATE.get("metrics_key") != key:
        _STATE["metrics"] = toolkit.make_metrics(tuple(names), device)
        _STATE["metrics_key"] = key
    return _STATE["metrics"]


def png_bytes(img: np.ndarray) -> bytes:
    """8-bit PNG of a linear float image clamped to [0, 1] (for figures and contact sheets)."""
    from PIL import Image

    arr = (np.clip(np.nan_to_num(img), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(arr).save(buf, format="PNG")
    return buf.getvalue()


def put_png(cache: StageCache, key: str, img: np.ndarray) -> None:
    cache.put_bytes("images", key, "png", png_bytes(img))


# --------------------------------------------------------------------------- score
@dataclass
class ScoreTask:
    cache_root: str
    key: str
    path: str
    lod: int | None
    scene_digest: str
    method: str
    params: Params  # resolved when the config was loaded
    seed: int
    train: list[dict] | None  # camera dicts, for the pruners that use cameras
    device: str
    toolkit: Toolkit = field(default_factory=Toolkit)
    label: str = ""  # what it computes, for task names and messages (scene, frame, method)

    def failed(self, message: str) -> dict:
        return {"key": self.key, "error": message, "seconds": 0.0}


def run_score(task: ScoreTask, scene=None) -> dict:
    """Score every splat with one method variant; store scores (npy) then their record (json).
    ``scene``: the loaded scene when the executor has it (else it is loaded here)."""
    from methods.registry import PruneContext, get_pruner

    cache = _cache(task.cache_root)
    out = {"key": task.key, "error": None, "seconds": 0.0}
    try:
        if scene is None:
            scene = _scene(task.toolkit, task.path, task.lod, task.scene_digest)
        spec = get_pruner(task.method)
        cams = [Camera.from_dict(c) for c in task.train] if task.train else None
        ctx = PruneContext(params=task.params, seed=task.seed, cameras=cams, device=task.device)
        t0 = time.perf_counter()
        scores = spec.score(scene, ctx)
        seconds = time.perf_counter() - t0
        cache.put_array("score", task.key, scores)
        cache.put_json("score", task.key, {"seconds": seconds, "n": len(scores)})
        out["seconds"] = seconds
    except Exception as err:  # a pruner failing on one scene is recorded, the run goes on
        out["error"] = task_error(err)
        out["trace"] = traceback.format_exc(limit=6)
    return out


# --------------------------------------------------------------------------- render + metrics
@dataclass
class MaskJob:
    metrics_key: str
    mask_key: str
    png: bool = False  # keep an image of this pruned render for the figures


@dataclass
class ViewTask:
    cache_root: str
    ref_key: str
    path: str
    lod: int | None
    scene_digest: str
    n_splats: int
    camera: dict
    renderer: str
    device: str
    background: tuple[float, float, float]
    metrics: tuple[str, ...]
    masks: list[MaskJob]  # pruned sets not measured yet (the planner checked the cache)
    render_ref: bool = True  # False: the reference render is cached, load it
    ref_png: bool = False
    toolkit: Toolkit = field(default_factory=Toolkit)
    label: str = ""  # what it computes, for task names and messages (scene, frame, view)
    #: the view's captured photo (the ``real`` protocol): every pruned render is also measured against
    #: it (``gt`` names), and with ``gt_key`` the unpruned render too (stored in the ``gt`` stage, the
    #: photo at the render size as its PNG)
    photo: str | None = None
    gt: tuple[str, ...] = ()
    gt_key: str | None = None

    def failed(self, message: str) -> dict:
        return {"ref_key": self.ref_key, "errors": [(None, message)], "done": 0}


def run_view(task: ViewTask, progress=None, scene=None, ref=None, keep_ref: bool = False) -> dict:
    """Reference render of one view (cached), then each not-yet-measured pruned set of it.

    The reference's metric features are computed once here and reused for every pruned render, and
    the view is projected once for all of them (:class:`ViewRenders`).
    ``progress(n)`` is called after each stored metrics entry (in-process runs only). ``scene``:
    the loaded scene, ``ref``: ``(image, alpha or None)`` of the reference rendered by an earlier
    task of this run, when the executor has them (else they are loaded / read from the cache).
    """
    from harness.metrics.registry import needs_alpha

    cache = _cache(task.cache_root)
    out = {"ref_key": task.ref_key, "errors": [], "done": 0}
    cam = Camera.from_dict(task.camera)
    measure = bool(task.masks) or task.gt_key is not None
    try:
        if scene is None:
            scene = _scene(task.toolkit, task.path, task.lod, task.scene_digest)
        om = needs_alpha(task.metrics)  # OM metrics: occupancy from both renders (stored with the reference)
        alpha = om or task.photo is not None  # a photo's OM metrics: the reference's occupancy
        renders = ViewRenders(_renderer(task.toolkit, task.renderer, task.device), scene, cam, task.background, alpha,
                              task.device)
        ref_img, ref_alpha = _reference(task, cache, renders, cam, ref, alpha and measure)
        _refuse_empty(ref_img, task.background, cam.name, measure)
        if task.ref_png:
            put_png(cache, task.ref_key, ref_img)
        if keep_ref:
            out["ref_images"] = (ref_img, ref_alpha)
        if measure:
            suite, feat_s = _register_reference(task, cache, cam, ref_img, ref_alpha if alpha else None, alpha)
            if task.masks:
                renders.prepare()
            step = suite.batch_size(cam.height, cam.width)  # 1 with the CPU forms: image by image
            for start in range(0, len(task.masks), step):
                for job, err in _measure_sets(task, cache, suite, renders, task.masks[start:start + step], feat_s, om):
                    if err is not None:
                        out["errors"].append((job.metrics_key, err))
                        continue
                    out["done"] += 1
                    if progress:
                        progress(1)
    except Exception as err:
        out["errors"].append((None, task_error(err)))
        out["trace"] = traceback.format_exc(limit=6)
    return out


def _refuse_empty(ref_img: np.ndarray, background, view: str, measure: bool) -> None:
    """ValueError when a view to be measured shows no splat: its identical empty renders would read
    as a perfect score (PSNR +inf, SSIM 1)."""
    if measure and np.array_equal(ref_img, np.broadcast_to(np.asarray(background, np.float32), ref_img.shape)):
        raise ValueError(f"view {view!r} shows no splat (its unpruned render is all background): there is "
                         "nothing to measure, and its identical empty renders would read as a perfect score")


def _reference(task: ViewTask, cache: StageCache, renders: ViewRenders, cam: Camera, given, want_alpha: bool):
    """The view's reference ``(image, alpha or None)``: handed in by the executor (when it passes
    its checks), else read from the cache, else rendered and stored (image, alpha, record). A cached
    reference that fails its checksum or shape is discarded and rendered again."""
    from harness.run.verify import alpha_check, image_check

    if given is not None and (task.render_ref or image_check(cam.width, cam.height)(given[0]) is not None):
        given = None
    ref = None if task.render_ref else given[0] if given is not None else \
        cache.get_array("render_ref", task.ref_key, count=False, check=image_check(cam.width, cam.height))
    ref_alpha = None
    if want_alpha and ref is not None:
        ref_alpha = given[1] if given is not None and given[1] is not None else \
            cache.get_array("render_alpha", task.ref_key, count=False, check=alpha_check(cam.width, cam.height))
    if ref is None or (want_alpha and ref_alpha is None):
        t0 = time.perf_counter()
        ref, ref_alpha = renders()
        if renders.with_alpha:
            cache.put_array("render_alpha", task.ref_key, ref_alpha)
        ref_rec = {"seconds": time.perf_counter() - t0, "height": int(ref.shape[0]), "width": int(ref.shape[1])}
        cache.put_array("render_ref", task.ref_key, ref)
        cache.put_json("render_ref", task.ref_key, ref_rec)
    return ref, ref_alpha


def _register_reference(task: ViewTask, cache: StageCache, cam: Camera, ref, ref_alpha, alpha: bool):
    """The metric suite with the view's reference registered (its features, its side of every
    metric; the photo and the unpruned render's ``gt`` entry where the view has a photo), and the
    seconds that took."""
    suite = _metrics(task.toolkit, task.metrics, task.device)
    t0 = time.perf_counter()
    extra = {"alpha": ref_alpha} if alpha else {}
    if task.photo is not None:
        from pathlib import Path

        from harness.io.photos import read_photo

        extra["photo"] = read_photo(Path(task.photo), cam.width, cam.height)
    suite.reference(task.ref_key, ref, **extra)
    feat_s = time.perf_counter() - t0
    if task.gt_key is not None:
        put_png(cache, task.gt_key, extra["photo"])
        cache.put_json("gt", task.gt_key, {**suite.photo_scores(task.ref_key), "seconds": feat_s})
    return suite, feat_s


def _render_sets(task: ViewTask, cache: StageCache, renders: ViewRenders, jobs: list[MaskJob],
                 on_device: bool = False) -> tuple[list, dict]:
    """([(job, image, alpha, render seconds)] of the pruned sets rendered, {id(job): error} of the
    others: a mask missing or failing verification, or a render that raised). The sets are drawn
    as one batch (:meth:`ViewRenders.many`: one read-back) with its seconds shared among them; a
    batch that raises is drawn again set by set, so that a failing set fails alone. ``on_device``:
    the batch's images and alphas are tensors on the study's device (:meth:`ViewRenders.many_on_device`)."""
    from harness.run.verify import mask_check

    keeps, failed = [], {}
    for job in jobs:
        try:
            packed = cache.get_array("masks", job.mask_key, count=False,
                                     check=mask_check(task.n_splats, digest=job.mask_key))
            if packed is None:
                raise RuntimeError(f"mask {job.mask_key[:12]} is missing or failed verification")
            keeps.append((job, np.unpackbits(packed, count=task.n_splats).astype(bool)))
        except Exception as err:
            failed[id(job)] = task_error(err)
    if len(keeps) > 1 or (on_device and keeps):
        try:
            t0 = time.perf_counter()
            outs = _draw_batch(renders, [keep for _, keep in keeps], on_device)
            each = (time.perf_counter() - t0) / len(keeps)
            return [(job, img, alpha, each) for (job, _), (img, alpha) in zip(keeps, outs)], failed
        except Exception:  # find which set fails: one by one below
            pass
    done = []
    for job, keep in keeps:
        try:
            t0 = time.perf_counter()
            img, img_alpha = renders(keep)
            done.append((job, img, img_alpha, time.perf_counter() - t0))
        except Exception as err:
            failed[id(job)] = task_error(err)
    return done, failed


def _draw_batch(renders: ViewRenders, keeps: list[np.ndarray], on_device: bool) -> list[tuple]:
    """``(image, alpha or None)`` of each pruned set drawn as one batch: host arrays, or with
    ``on_device`` views into the batch's tensors on the study's device."""
    if not on_device:
        return renders.many(keeps)
    images, alphas = renders.many_on_device(keeps)
    return [(images[i], None if alphas is None else alphas[i]) for i in range(len(keeps))]


def _measure_sets(task: ViewTask, cache: StageCache, suite, renders: ViewRenders, jobs: list[MaskJob],
                  feat_s: float, om: bool) -> list[tuple[MaskJob, str | None]]:
    """Render pruned sets of the view (their splats filtered from the view's packing), score them
    against the reference (and the photo) in one batch, store each one's metrics entry (and its PNG
    when asked). Returns each job with its error (None: stored); a job whose mask or render fails
    is left out of the batch, a batch whose scoring fails fails all of its jobs.
    ``metrics_s`` of an entry is its share of the batch's scoring."""
    on_device = bool(getattr(suite, "torch_forms", False)) and renders.frames_on_device()
    done, result = _render_sets(task, cache, renders, jobs, on_device)  # result: id(job) -> error (None: stored)
    in_order = lambda: [(job, result[id(job)]) for job in jobs]  # noqa: E731
    if not done:
        return in_order()
    t1 = time.perf_counter()
    try:
        images = stacked([img for _, img, _, _ in done])
        rows = suite.score_many(task.ref_key, images, stacked([a for _, _, a, _ in done])) if om else \
            suite.score_many(task.ref_key, images)
    except Exception as err:
        result.update({id(job): task_error(err) for job, *_ in done})
        return in_order()
    metrics_s = (time.perf_counter() - t1) / len(done)
    for (job, img, _, render_s), values in zip(done, rows):
        try:
            if job.png:
                put_png(cache, job.metrics_key, host_array(img))
            rec = {k: float(values[k]) for k in (*task.metrics, *task.gt, "occupancy") if k in values}
            # render_s: this set's own render (its share of the view's projection is view_pack_s)
            rec.update(render_s=render_s, metrics_s=metrics_s, ref_features_s=feat_s, view_pack_s=renders.pack_s)
            cache.put_json("metrics", job.metrics_key, rec)
            result[id(job)] = None
        except Exception as err:
            result[id(job)] = task_error(err)
    return in_order()
