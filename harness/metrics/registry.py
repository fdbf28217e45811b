"""The metrics a run can measure: one registration per metric carries everything every tool needs.

    register_metric("psnr", compute=psnr_pair, higher_is_better=True, valid_range=(0, inf),
                    inf_if_identical=True, unit="dB", cost="psnr", family="3dgs", label="PSNR", digits=2)

* ``compute(reference, test) -> float`` on two float32 (H, W, 3) images in [0, 1] (it may also take
  the keywords ``device`` and ``mask``; with ``prepare(reference, device)`` given, ``reference`` is
  what ``prepare`` made of it, computed once per view). A family that computes its metrics together
  (the MPEG tool's set shares its 8-bit/YUV reference planes) registers a joint computer with
  :func:`register_family`, and its members no ``compute`` of their own.
* ``valid_range`` (and ``inf_if_identical``: +inf for identical images, PSNR's convention): what
  the stage cache accepts as a stored value (:func:`harness.run.verify.metrics_check`).
* ``cost``: the calibrated pass it costs per pixel (:data:`PASS_KINDS`; ``harness plan --estimate``).
* ``needs_alpha``: the renders' accumulated alpha (the occupancy-masked metrics).
* ``unit="dB"``: a PSNR; views at or above 100 dB are *near-identical* (:mod:`harness.report.stats`).
* ``label``, ``digits``, ``higher_is_better``: how tables show it; ``masks``: the full-frame metric an
  occupancy-masked one restricts (shown beside it); ``family``: the set a config asks for by name
  (``metrics: [3dgs]``); ``check()``: raises :class:`~harness.core.errors.InputError` before any work
  when the metric cannot run here (weights not fetched).

Every metric gets a ``gt_`` twin (the same measure of a render against the view's captured photo).
Built-in registrations live in :mod:`harness.metrics.builtin`; third-party packages add theirs through
the ``harness.metrics`` entry-point group (a module whose import calls :func:`register_metric`),
like pruners. Cheap to import (no torch): configs and tables use it.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass, replace

from harness.core.registry import Registry

ENTRY_POINT_GROUP = "harness.metrics"
#: the calibrated per-pixel passes a metric can cost (:class:`harness.run.unit_costs.UnitCosts`):
#: an LPIPS-VGG trunk, a 3-plane SSIM, a PSNR-like pass (squared errors, 8-bit, colour conversion)
PASS_KINDS = ("lpips", "ssim", "psnr")
#: metrics against a view's captured photo (the paper's "against captured ground-truth images"):
#: ``gt_<name>`` for every registered ``<name>``, measured automatically where a view has a photo,
#: never asked for in a config; the others compare a pruned render with the unpruned render
GT_PREFIX = "gt_"
GT_FAMILY = "gt"


@dataclass(frozen=True)
class MetricSpec:
    name: str
    label: str
    higher_is_better: bool
    digits: int
    family: str
    doc: str = ""
    compute: Callable | None = None
    valid_range: tuple[float, float] = (-math.inf, math.inf)
    inf_if_identical: bool = False
    cost: str = "psnr"
    needs_alpha: bool = False
    unit: str = ""
    masks: str | None = None
    prepare: Callable | None = None
    check: Callable | None = None
    #: a photo metric measured whenever this metric is (``gt_psnr_om`` with ``psnr``)
    with_metric: str | None = None

    @property
    def heading(self) -> str:
        """Table heading with the direction arrow: ``PSNR (↑)``."""
        return f"{self.label} ({'↑' if self.higher_is_better else '↓'})"

    def better(self, a: float, b: float) -> bool:
        """Is value ``a`` better than ``b``?"""
        return a > b if self.higher_is_better else a < b

    @property
    def is_db(self) -> bool:
        return self.unit == "dB"

    @property
    def is_gt(self) -> bool:
        return self.family == GT_FAMILY

    def problem(self, v: float) -> str | None:
        """Why ``v`` cannot be a value of this metric (None: it can)."""
        lo, hi = self.valid_range
        if math.isinf(v) and v > 0 and self.inf_if_identical:
            return None
        if not math.isfinite(v):
            return f"{self.name} {v!r} is not finite"
        if v < lo or v > hi:
            if lo == 0 and hi == math.inf:
                return f"{self.name} {v!r} is negative"
            return f"{self.name} {v!r} is outside [{lo:g}, {hi:g}]"
        return None

    def identity(self) -> tuple:
        """What tells a harmless re-registration (a module imported twice) from a clash."""
        fn = lambda f: None if f is None else (f.__module__, f.__qualname__)  # noqa: E731
        return (replace(self, compute=None, prepare=None, check=None), fn(self.compute), fn(self.prepare))

    def takes(self, keyword: str) -> bool:
        """Does ``compute`` accept the keyword ``keyword`` (``device``, ``mask``)?"""
        try:
            return keyword in inspect.signature(self.compute).parameters
        except (TypeError, ValueError):
            return False


@dataclass(frozen=True)
class MetricFamily:
    """Metrics computed together: ``compute(reference, test, names, mask) -> {name: value, …}``
    (plus ``occupancy`` % when an occupancy-masked one is asked for); ``prepare(reference)``: its
    reference side, computed once per view and passed as ``reference``."""

    name: str
    compute: Callable
    prepare: Callable | None = None


#: every metric :class:`harness.metrics.suite.MetricSuite` computes, built-ins first
METRICS: Registry[MetricSpec] = Registry("metric", modules=("harness.metrics.builtin",), group=ENTRY_POINT_GROUP)
FAMILIES: dict[str, MetricFamily] = {}


def register_family(name: str, *, compute: Callable, prepare: Callable | None = None) -> MetricFamily:
    """Register the joint computer of the metrics of family ``name`` (module docstring)."""
    fam = MetricFamily(name, compute, prepare)
    FAMILIES[name] = fam
    return fam


def register_metric(name: str, *, higher_is_better: bool, cost: str, compute: Callable | None = None,
                    valid_range: tuple[float, float] = (-math.inf, math.inf), needs_alpha: bool = False,
                    family: str = "other", label: str | None = None, digits: int = 3, unit: str = "",
                    doc: str = "", inf_if_identical: bool = False, masks: str | None = None,
                    prepare: Callable | None = None, check: Callable | None = None,
                    with_metric: str | None = None) -> MetricSpec:
    """Register metric ``name`` (module docstring) and its ``gt_`` twin; returns its spec."""
    if cost not in PASS_KINDS:
        raise ValueError(f"metric {name!r}: cost must be one of {', '.join(PASS_KINDS)}, got {cost!r}")
    lo, hi = (float(x) for x in valid_range)
    if not lo <= hi:
        raise ValueError(f"metric {name!r}: valid_range {valid_range!r} is empty")
    if compute is None and family not in FAMILIES and family != GT_FAMILY:
        raise ValueError(f"metric {name!r}: give compute=, or register family {family!r}'s joint computer first")
    spec = MetricSpec(name, label or name, bool(higher_is_better), int(digits), family, doc, compute, (lo, hi),
                      bool(inf_if_identical), cost, bool(needs_alpha), unit, masks, prepare, check, with_metric)
    METRICS.add(name, spec, same=lambda a, b: a.identity() == b.identity())
    twin = GT_PREFIX + name
    if family != GT_FAMILY and not METRICS.registered(twin):  # a photo metric of that name stays
        gt = replace(spec, name=twin, label=f"{spec.label} vs photo", family=GT_FAMILY,
                     masks=GT_PREFIX + masks if masks else None,
                     doc=f"{doc}; the render against the view's captured photo".lstrip("; "))
        METRICS.add(twin, gt, same=lambda a, b: a.identity() == b.identity())
    return spec


def spec(name: str) -> MetricSpec | None:
    """The registered metric ``name``, or None (a result column that is not a metric)."""
    try:
        return METRICS.get(name)
    except KeyError:
        return None


def expand(names) -> tuple[str, ...]:
    """Metric names with family names (``3dgs``) replaced by their members, duplicates dropped."""
    families = {}
    for m in METRICS:
        families.setdefault(m.family, []).append(m.name)
    out: list[str] = []
    for n in names:
        for m in families.get(n, [n]):
            if m not in out:
                out.append(m)
    return tuple(out)


def family_names(family: str) -> tuple[str, ...]:
    """The metric names of ``family``, registry order."""
    return tuple(m.name for m in METRICS if m.family == family)


def requestable() -> list[str]:
    """Metric and family names a config or ``harness compare`` may ask for (photo metrics are not
    asked for: they come with the photos)."""
    own = [m for m in METRICS if m.family != GT_FAMILY]
    return [m.name for m in own] + sorted({m.family for m in own})


def is_gt(name: str) -> bool:
    """Is ``name`` a metric against the captured photo?"""
    return str(name).startswith(GT_PREFIX)


def is_db(name: str) -> bool:
    """Is ``name`` a registered metric in dB (a PSNR)?"""
    s = spec(name)
    return s is not None and s.is_db


def gt_names(names) -> tuple[str, ...]:
    """The photo metrics measured beside ``names``: each one's ``gt_`` twin, and the photo-only
    metrics registered ``with_metric`` one of them (``gt_psnr_om`` with ``psnr``)."""
    out = [GT_PREFIX + n for n in names if not is_gt(n)]
    extra = [m.name for m in METRICS if m.with_metric is not None and m.with_metric in names]
    return tuple(dict.fromkeys(out + extra))


def needs_alpha(names) -> bool:
    """Do any of ``names`` need the renders' alpha (the occupancy-masked MPEG metrics)?"""
    return any(s.needs_alpha for n in names if (s := spec(n)) is not None)


def check_available(names) -> None:
    """Fail before any work when one of ``names`` cannot run here (its ``check`` raises)."""
    for n in names:
        s = spec(n)
        if s is not None and s.check is not None:
            s.check()
