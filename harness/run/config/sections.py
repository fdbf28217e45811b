"""The sections of a run config, each a dataclass of typed ``param(...)`` fields (one default, range
and doc each; read by :func:`harness.run.config.schema.read_section`), with the readers of the values that
are no scalars. :mod:`harness.run.config.run_config` reads a whole config with them.
"""

from __future__ import annotations

from dataclasses import dataclass

from harness.core.cameras import MAX_SIDE
from harness.core.errors import InputError
from harness.core.params import Params, param
from harness.core.suggest import unknown
from harness.io.capture import CaptureSpec
from harness.metrics.registry import expand, requestable
from harness.report.plots import PLOTS
from harness.report.tables import TABLES
from harness.run.config.checks import expand_env
from harness.run.config.checks import fractions as _fractions
from harness.run.config.checks import mapping as _mapping
from harness.run.config.checks import names as _names
from harness.run.config.checks import num as _num
from harness.run.config.checks import string as _str
from harness.run.config.schema import read_section
from harness.run.config.views import capture as _capture
from harness.views import rigs
from renderers import RENDERERS

KINDS = ("forward-facing", "object-centric")
#: the smallest render a study may ask for (px, longest side): below the SSIM window's 11 px a
#: render is no test of a pruner
MIN_SIDE = 8


def pruner(name: str, where: str, src):
    """The registered pruner ``name``, or an InputError with the known names and the close ones."""
    from methods.registry import get_pruner, list_pruners

    try:
        return get_pruner(name)
    except KeyError:
        raise InputError(src, f"{where}: {unknown('method', name, [p.name for p in list_pruners()])}") from None


# --------------------------------------------------------------------------- value readers (parse=)
def _background(v, key, src) -> tuple[float, float, float]:
    if not isinstance(v, list) or len(v) != 3:
        raise InputError(src, f"{key}: expected three numbers in [0, 1]")
    return tuple(float(_num(x, f"{key}[{i}]", src, lo=0, hi=1)) for i, x in enumerate(v))


def _metrics(v, key, src) -> tuple[str, ...]:
    if not isinstance(v, list) or not v:
        raise InputError(src, f"{key}: expected a non-empty list of metric or metric-set names")
    return expand(_names(v, requestable(), key, src, "metric or metric set"))


def _path(v, key, src) -> str:
    """A path or name, ``${VAR:-default}`` expanded."""
    return expand_env(_str(v, key, src))


def _text_list(what: str):
    def read(v, key, src) -> tuple[str, ...]:
        if not isinstance(v, list) or not all(isinstance(t, str) for t in v):
            raise InputError(src, f"{key}: expected a list of {what}")
        return tuple(v)
    return read


def _mapping_value(v, key, src) -> dict:
    return dict(_mapping(v, key, src))


def _fraction_list(v, key, src) -> tuple[float, ...]:
    return _fractions(v, key, src)


def _registered(kind: str, names):
    """A list of registered ``kind`` names: ``[]`` is none of them, ``null`` every one (the default)."""
    def read(v, key, src) -> tuple[str, ...]:
        return tuple(names) if v is None else _names(v, names, key, src, kind)
    return read


def pruner_name(v, key, src) -> str:
    name = _str(v, key, src)
    pruner(name, key, src)
    return name


# --------------------------------------------------------------------------- sections
@dataclass(frozen=True)
class Protocol:
    """How every scene is evaluated (``protocol:``)."""

    longest_side: int = param(rigs.LONGEST_SIDE, ge=MIN_SIDE, le=MAX_SIDE,
                              doc="render resolution: the longest image side (px)")
    aspect: float | None = param(None, ge=0.1, le=10,
                                 doc="width / height of rig views (none: the rig's own, a named dataset's, else 4/3)")
    background: tuple[float, float, float] = param((0.0, 0.0, 0.0), parse=_background,
                                                   doc="background colour (R, G, B in [0, 1])")
    renderer: str = param("gl", choices=lambda: RENDERERS.names(), doc="renderer (renderers registry)")
    device: str = param("cpu", doc="torch device for metrics and camera-aware pruners")
    metrics: tuple[str, ...] = param(("psnr", "ssim", "lpips"), parse=_metrics,
                                     doc="metrics or metric families (harness.metrics registry)")
    seed: int = param(0, ge=0, doc="seed of rigs and random pruners")
    n_train: int = param(rigs.N_TRAIN, ge=0, le=rigs.MAX_VIEWS, doc="rig views handed to camera-aware pruners")
    n_test: int = param(rigs.N_TEST, ge=1, le=rigs.MAX_VIEWS, doc="held-out rig views that are measured")


def _cameras(v, key, src) -> CameraSpec:
    d = _mapping(v, key, src)
    spec = read_section(CameraSpec, d, key, src, defaults={"path": None})
    if spec["path"] is None:
        raise InputError(src, f"{key}.path: required (the cameras file)")
    if not spec["test"] and not spec["test_every"]:
        raise InputError(src, f"{key}: give the held-out views as `test: [names]` or `test_every: k`")
    return CameraSpec(**spec)


@dataclass(frozen=True)
class CameraSpec:
    """Cameras from a file; held-out views by name (``test``) or every k-th view (``test_every``)."""

    path: str = param(None, parse=_path, doc="the cameras file")
    test: tuple[str, ...] = param((), parse=_text_list("view names"), doc="held-out views by name")
    test_every: int = param(0, ge=0, doc="every k-th view is held out")


@dataclass(frozen=True)
class SceneSpec:
    name: str
    label: str
    source: str | None = param(None, parse=_path,
                               doc="dataset name (harness.io.datasets) or a path; default: the name")
    frames: str | None = param(None, parse=_path, doc="instead of source: a glob of per-frame files (one sequence)")
    kind: str = param("object-centric", choices=KINDS, doc="forward-facing picks the `forward` rig for rig: default")
    rig: str = param("default", choices=rigs.RIG_CHOICES, doc="synthetic rig (harness.views.rigs)")
    cameras: CameraSpec | None = param(None, parse=_cameras, doc="cameras from a file, instead of a rig")
    lod: int | None = param(None, ge=0, doc="SOG level of detail")
    n_train: int = param(rigs.N_TRAIN, ge=0, le=rigs.MAX_VIEWS, doc="this scene's protocol.n_train")
    n_test: int = param(rigs.N_TEST, ge=1, le=rigs.MAX_VIEWS, doc="this scene's protocol.n_test")
    suites: tuple[str, ...] = param((), parse=_text_list("tags"), doc="free tags")
    #: an MPEG content folder (harness.io.sequences): per-frame PLYs + cameras, native resolution,
    #: every camera measured unless ``test`` / ``test_every`` name the views
    sequence: str | None = param(None, parse=_path, doc="an MPEG content folder (harness.io.sequences)")
    test: tuple[str, ...] = param((), parse=_text_list("view names"), doc="sequence: held-out views by name")
    test_every: int = param(0, ge=0, doc="sequence: every k-th camera is held out")
    width: int | None = param(None, ge=1, le=MAX_SIDE, doc="sequence: image width for header cameras without one")
    height: int | None = param(None, ge=1, le=MAX_SIDE, doc="sequence: image height for header cameras without one")
    #: absent files are skipped with a message (MPEG content not everyone has); otherwise a scene
    #: that cannot be found is an error before any work (:func:`harness.run.plan.check_sources`)
    optional: bool = param(False, doc="skip the scene when its files are absent")
    #: the scene's capture (real cameras, split, photos; harness.io.capture) for the `real` protocol;
    #: None: a named scene's own (SCENE_CAPTURES), if any; False: none (`capture: false`)
    capture: CaptureSpec | bool | None = param(None, parse=_capture, doc="the real capture (harness.io.capture)")


@dataclass(frozen=True)
class MethodVariant:
    """One (pruner, resolved parameters) to evaluate at ``ratios`` on ``scenes`` (None = all)."""

    method: str
    variant: str
    params: Params
    ratios: tuple[float, ...]
    scenes: tuple[str, ...] | None = None
    #: the held-out view protocols it is measured under (None = every protocol of the config)
    protocols: tuple[str, ...] | None = None

    @property
    def key(self) -> str:
        return f"{self.method}[{self.variant}]"

    def measures(self, protocol: str) -> bool:
        """Whether its pruned sets are measured on ``protocol``'s held-out views."""
        return self.protocols is None or protocol in self.protocols


@dataclass(frozen=True)
class MethodEntry:
    """One ``methods[]`` entry as written, before its sweep is expanded into variants."""

    name: str = param(None, parse=pruner_name, doc="a registered pruner")
    variant: str | None = param(None, doc="row label of this entry (default: default, or the sweep values)")
    params: dict = param(None, parse=_mapping_value, doc="the pruner's parameters")
    sweep: dict = param(None, parse=_mapping_value, doc="lists of values: one variant per combination")
    ratios: tuple[float, ...] | None = param(
        None, parse=_fraction_list, doc="pruning ratios (default: the top level's)"
    )
    keep: tuple[float, ...] | None = param(None, parse=_fraction_list, doc="keep fractions (ratio = 1 - keep)")
    scenes: tuple[str, ...] | None = param(None, parse=_text_list("scene names"), doc="restrict to these scenes")
    protocols: tuple[str, ...] | None = param(None, parse=_text_list("protocol names"),
                                              doc="measure only under these of the config's view protocols")


@dataclass(frozen=True)
class Settings:
    """The top level's own values (the sections have theirs)."""

    name: str | None = param(None, doc="run name (default: the file's stem)")
    output: str | None = param(None, parse=_path, doc="results folder (default: runs/<name>)")
    workers: int = param(1, ge=1, le=256, doc="local process pool size (--workers overrides)")
    anchor: str = param("lightgs", parse=pruner_name, doc="BD-rate / BD-PSNR anchor of the bd table")
    ratios: tuple[float, ...] = param((), parse=_fraction_list, doc="default pruning ratios of every method")
    keep: tuple[float, ...] = param((), parse=_fraction_list, doc="default keep fractions, merged with ratios")
    tables: tuple[str, ...] = param(TABLES, parse=_registered("table", TABLES), doc="tables to write")
    plots: tuple[str, ...] = param(PLOTS, parse=_registered("plot", PLOTS), doc="plots to draw")
