"""The sections of a run config, each a dataclass of typed ``config_param(...)`` fields (one default,
range, doc and what the value changes each; read by :func:`harness.run.config.schema.read_section`),
with the readers of the values that are no scalars. :mod:`harness.run.config.run_config` reads a
whole config with them.
"""

from __future__ import annotations

from dataclasses import dataclass

from harness.core.cameras import MAX_SIDE
from harness.core.errors import InputError
from harness.core.params import Params
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
from harness.run.config.schema import config_param, read_section
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
    def read(v, key, src) -> tuple[str, ...]:
        return _names(v, names, key, src, kind)
    read.registered = kind  # the default is every registered one (docs/config.md says so)
    return read


def pruner_name(v, key, src) -> str:
    name = _str(v, key, src)
    pruner(name, key, src)
    return name


# --------------------------------------------------------------------------- sections
@dataclass(frozen=True)
class Protocol:
    """How every scene is evaluated (``protocol:``)."""

    longest_side: int = config_param(rigs.LONGEST_SIDE, ge=MIN_SIDE, le=MAX_SIDE,
                                     changes=("rig_views", "file_views", "protocol_views"),
                                     doc="render resolution: the longest image side (px)")
    aspect: float | None = config_param(
        None, ge=0.1, le=10, changes=("rig_views", "protocol_views"),
        doc="width / height of rig views (none: the rig's own, a named dataset's, else 4/3)")
    background: tuple[float, float, float] = config_param(
        (0.0, 0.0, 0.0), parse=_background, changes=("render_ref",), doc="background colour (R, G, B in [0, 1])")
    renderer: str = config_param("gl", choices=lambda: RENDERERS.names(), changes=("render_ref",),
                                 doc="renderer (renderers registry)")
    #: in the score keys of camera-aware pruners only (what it may change); the metrics keys never
    #: held it, and deriving them keeps them as they were
    device: str = config_param("cpu", changes=("aware_score",),
                               doc="torch device for metrics and camera-aware pruners")
    metrics: tuple[str, ...] = config_param(("psnr", "ssim", "lpips"), parse=_metrics, changes=("metrics", "gt"),
                                            doc="metrics or metric families (harness.metrics registry)")
    seed: int = config_param(0, ge=0, changes=("score", "rig_views", "protocol_views"),
                             doc="seed of rigs and random pruners")
    #: the defaults of each scene's own n_train / n_test, which are what the view keys hold
    n_train: int = config_param(rigs.N_TRAIN, ge=0, le=rigs.MAX_VIEWS, changes=(),
                                doc="rig views handed to camera-aware pruners (each scene's default)")
    n_test: int = config_param(rigs.N_TEST, ge=1, le=rigs.MAX_VIEWS, changes=(),
                               doc="held-out rig views that are measured (each scene's default)")


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

    path: str = config_param(None, parse=_path, changes="content", doc="the cameras file")
    test: tuple[str, ...] = config_param((), parse=_text_list("view names"), changes=("file_views",),
                                         doc="held-out views by name")
    test_every: int = config_param(0, ge=0, changes=("file_views",), doc="every k-th view is held out")


@dataclass(frozen=True)
class SceneSpec:
    name: str
    label: str
    #: by content (the scene's files); a named dataset's name is in the view keys too, beside them
    source: str | None = config_param(None, parse=_path, changes="content",
                                      doc="dataset name (harness.io.datasets) or a path; default: the name")
    frames: str | None = config_param(None, parse=_path, changes="content",
                                      doc="instead of source: a glob of per-frame files (one sequence)")
    kind: str = config_param("object-centric", choices=KINDS, changes=("rig_views", "protocol_views"),
                             doc="forward-facing picks the `forward` rig for rig: default")
    rig: str = config_param("default", choices=rigs.RIG_CHOICES, changes=("rig_views", "protocol_views"),
                            doc="synthetic rig (harness.views.rigs)")
    cameras: CameraSpec | None = config_param(None, parse=_cameras, changes="content",
                                              doc="cameras from a file, instead of a rig")
    lod: int | None = config_param(None, ge=0, changes=("load",), doc="SOG level of detail")
    n_train: int = config_param(rigs.N_TRAIN, ge=0, le=rigs.MAX_VIEWS, changes=("rig_views", "protocol_views"),
                                doc="this scene's protocol.n_train")
    n_test: int = config_param(rigs.N_TEST, ge=1, le=rigs.MAX_VIEWS, changes=("rig_views", "protocol_views"),
                               doc="this scene's protocol.n_test")
    suites: tuple[str, ...] = config_param((), parse=_text_list("tags"), changes=(), doc="free tags")
    #: an MPEG content folder (harness.io.sequences): per-frame PLYs + cameras, native resolution,
    #: every camera measured unless ``test`` / ``test_every`` name the views
    sequence: str | None = config_param(None, parse=_path, changes="content",
                                        doc="an MPEG content folder (harness.io.sequences)")
    test: tuple[str, ...] = config_param((), parse=_text_list("view names"), changes=("sequence_views",),
                                         doc="sequence: held-out views by name")
    test_every: int = config_param(0, ge=0, changes=("sequence_views",),
                                   doc="sequence: every k-th camera is held out")
    width: int | None = config_param(None, ge=1, le=MAX_SIDE, changes=("sequence_views",),
                                     doc="sequence: image width for header cameras without one")
    height: int | None = config_param(None, ge=1, le=MAX_SIDE, changes=("sequence_views",),
                                      doc="sequence: image height for header cameras without one")
    #: absent files are skipped with a message (MPEG content not everyone has); otherwise a scene
    #: that cannot be found is an error before any work (:func:`harness.run.sources.check_sources`)
    optional: bool = config_param(False, changes=(), doc="skip the scene when its files are absent")
    #: the scene's capture (real cameras, split, photos; harness.io.capture) for the `real` protocol;
    #: None: a named scene's own (SCENE_CAPTURES), if any; False: none (`capture: false`)
    capture: CaptureSpec | bool | None = config_param(None, parse=_capture, changes="content",
                                                      doc="the real capture (harness.io.capture)")


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

    name: str = config_param(None, parse=pruner_name, changes=("score",), doc="a registered pruner")
    variant: str | None = config_param(None, changes=(),
                                       doc="row label of this entry (default: default, or the sweep values)")
    params: dict = config_param(None, parse=_mapping_value, changes=("score",), doc="the pruner's parameters")
    sweep: dict = config_param(None, parse=_mapping_value, changes=("score",),
                               doc="lists of values: one variant per combination")
    ratios: tuple[float, ...] | None = config_param(None, parse=_fraction_list, changes=("prune",),
                                                    doc="pruning ratios (default: the top level's)")
    keep: tuple[float, ...] | None = config_param(None, parse=_fraction_list, changes=("prune",),
                                                  doc="keep fractions (ratio = 1 - keep)")
    scenes: tuple[str, ...] | None = config_param(None, parse=_text_list("scene names"), changes=(),
                                                  doc="restrict to these scenes")
    protocols: tuple[str, ...] | None = config_param(None, parse=_text_list("protocol names"), changes=(),
                                                     doc="measure only under these of the config's view protocols")


@dataclass(frozen=True)
class Settings:
    """The top level's own values (the sections have theirs)."""

    name: str | None = config_param(None, changes=(), doc="run name (default: the file's stem)")
    output: str | None = config_param(None, parse=_path, changes=(), doc="results folder (default: runs/<name>)")
    workers: int = config_param(1, ge=1, le=256, changes=(), doc="local process pool size (--workers overrides)")
    anchor: str = config_param("lightgs", parse=pruner_name, changes=(),
                               doc="BD-rate / BD-PSNR anchor of the bd table")
    ratios: tuple[float, ...] = config_param((), parse=_fraction_list, changes=("prune",),
                                             doc="default pruning ratios of every method")
    keep: tuple[float, ...] = config_param((), parse=_fraction_list, changes=("prune",),
                                           doc="default keep fractions, merged with ratios")
    tables: tuple[str, ...] = config_param(TABLES, parse=_registered("table", TABLES), changes=(),
                                           doc="tables to write")
    plots: tuple[str, ...] = config_param(PLOTS, parse=_registered("plot", PLOTS), changes=(), doc="plots to draw")
