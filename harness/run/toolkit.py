"""The pieces a run orchestrates, behind one small seam so tests can inject fakes.

:class:`Toolkit` bundles the callables the runner uses — scene loading, dataset name resolution,
rigs, camera files, renderers, metrics. The default toolkit imports the real modules lazily
(:mod:`harness.io.scenes`, :mod:`harness.io.datasets`, :mod:`harness.views.rigs`, :mod:`harness.io.cameras`,
:mod:`renderers`, :mod:`harness.metrics`). A toolkit travels to pool workers by pickling, so every
callable in it must be a module-level function.

Each entry also names the modules whose source is its "version" in cache keys
(see :func:`harness.run.cache.versions.code_digest`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path


def load_scene(path: str, lod: int | None = None):
    from harness.io.scenes import load_scene as _load

    return _load(path, lod=lod)


def resolve_dataset(name: str) -> Path | None:
    """Path of a named dataset scene, or None when ``name`` is not a dataset name.

    A named scene that is not on this machine resolves to its expected path (which then does not
    exist); the runner reports it as absent with :func:`harness.io.datasets.missing_reason`.
    """
    from harness.io import datasets

    return datasets.scene_path(name) if name in datasets.SCENES else None


def make_rig(rig: str, scene, *, kind: str, dataset: str | None, n_train: int, n_test: int,
             longest_side: int, aspect: float | None, seed: int):
    """(rig name, train, test) cameras from a synthetic rig (:func:`harness.views.rigs.scene_rig`).

    ``rig='default'``: the named dataset's own rig (its up axis, aspect and elevations); for other
    scenes ``forward`` when the config calls the scene forward-facing, else ``auto`` (room or
    orbit). ``aspect`` (None = the rig's own) overrides the table's when given.
    """
    from harness.views import rigs

    if rig == "default" and dataset not in rigs.SCENE_RIGS and kind == "forward-facing":
        rig = "forward"
    views = rigs.scene_rig(dataset, scene, rig, n_train=n_train, n_test=n_test, longest_side=longest_side,
                           aspect=aspect, seed=seed)
    return views.rig or rig, list(views.train), list(views.test)


def load_cameras(path: str):
    from harness.io.cameras import load_cameras as _load

    return _load(path)


def make_renderer(name: str, device: str):
    from renderers import get_renderer

    return get_renderer(name, device)


def make_metrics(names: tuple[str, ...], device: str):
    """A metric suite (:class:`harness.metrics.suite.MetricSuite`) with ``reference(key, img, alpha=)``,
    ``batch_size(h, w)`` and ``score_many(key, imgs, alphas) -> [dict]``; one view's features in
    memory at a time (a view task measures all its pruned sets before the next view), its pruned
    images in batches of ``batch_size`` (several on CUDA, one with the CPU forms)."""
    from harness.metrics.suite import MetricSuite

    return MetricSuite(names=names, device=device, max_in_memory=1)


def check_metrics(names: tuple[str, ...]) -> None:
    """Fail before any work when a metric cannot run (its registered ``check``: LPIPS-VGG weights
    not fetched -> InputError)."""
    from harness.metrics.registry import check_available

    check_available(names)


def _reader_modules() -> tuple[str, ...]:
    """Every registered scene format's reading code (:func:`harness.io.formats.reader_modules`)."""
    from harness.io.formats import reader_modules

    return reader_modules()


@dataclass(frozen=True)
class Toolkit:
    load_scene: Callable = load_scene
    resolve_dataset: Callable = resolve_dataset
    make_rig: Callable = make_rig
    load_cameras: Callable = load_cameras
    make_renderer: Callable = make_renderer
    make_metrics: Callable = make_metrics
    check_metrics: Callable = check_metrics
    #: module names whose source versions each stage (cache-key "code" component)
    reader_modules: tuple[str, ...] = field(default_factory=lambda: _reader_modules())
    rig_modules: tuple[str, ...] = ("harness.views.rigs", "harness.views.independent", "harness.views.placement",
                                    "harness.core.cameras", "harness.core.sphere")
    #: whole packages: renderers and metrics import their shared code lazily, inside functions, so a
    #: module-level import closure would miss it (over-invalidation is the safe side)
    renderer_modules: tuple[str, ...] = ("renderers",)
    metric_modules: tuple[str, ...] = ("harness.metrics",)
    #: extra modules each worker imports first (e.g. a plugin registering pruners)
    imports: tuple[str, ...] = field(default_factory=tuple)
    #: modules each worker imports before anything else, e.g. one that must not be loaded after an
    #: llvmpipe EGL context exists (triton segfaults then: the GL renderer imports it first itself, and
    #: LPIPS no longer imports torchvision/lpips, which pulled it in)
    preload: tuple[str, ...] = ()
