"""The metrics a run can measure: one registration per metric carries everything every tool needs.

    register_metric("mae", mae, higher_is_better=False)          # the minimum: every other field defaults

    register_metric("psnr", compute=psnr_pair, higher_is_better=True, valid_range=(0, inf),
                    inf_if_identical=True, unit="dB", cost="psnr", family="3dgs", label="PSNR", digits=2,
                    tolerance=0.5)

* ``compute(reference, test) -> float`` on two float32 (H, W, 3) images in [0, 1] (it may also take
  the keywords ``device`` and ``mask``; with ``prepare(reference, device)`` given, ``reference`` is
  what ``prepare`` made of it, computed once per view). A family that computes its metrics together
  (the MPEG tool's set shares its 8-bit/YUV reference planes) registers a joint computer with
  :func:`register_family`, and its members no ``compute`` of their own.
* ``higher_is_better``: the direction every table, plot, verdict and tracking check reads.
* ``valid_range`` (default unbounded; and ``inf_if_identical``: +inf for identical images, PSNR's
  convention): what the stage cache accepts as a stored value (:func:`harness.run.verify.metrics_check`).
* ``cost`` (default ``"psnr"``: like a PSNR pass): the calibrated pass it costs per pixel
  (:data:`PASS_KINDS`; ``harness plan --estimate``).
* ``needs_alpha``: the renders' accumulated alpha (the occupancy-masked metrics).
* ``unit="dB"``: a PSNR; views at or above 100 dB are *near-identical* (:mod:`harness.report.stats`).
* ``label`` (default the name), ``digits`` (default 3): how tables show it; ``masks``: the full-frame
  metric an occupancy-masked one restricts (shown beside it); ``family`` (default ``"other"``): the
  set a config asks for by name (``metrics: [3dgs]``); ``check()``: raises
  :class:`~harness.core.errors.InputError` before any work when the metric cannot run here (weights
  not fetched).
* ``tolerance`` (default None: not tracked): how far a run's mean may move the wrong way before
  ``harness track`` calls it a regression.

A registration the registry cannot accept is one :class:`~harness.core.registry.RegistrationError`
naming the metric and the field. Every metric gets a ``gt_`` twin (the same measure of a render
against the view's captured photo). The metrics of :data:`HEADLINE_FAMILY` are the ones a command
measures when it is given none, and come first in results and summaries. Built-in registrations live
in :mod:`harness.metrics.builtin`; third-party packages add theirs through the ``harness.metrics``
entry-point group (a module whose import calls :func:`register_metric`), like pruners. Cheap to
import (no torch): configs and tables use it.
"""

from __future__ import annotations

import inspect
import math
import re
from collections.abc import Callable
from dataclasses import dataclass, replace

from harness.core import plugins
from harness.core.registry import RegistrationError, Registry

ENTRY_POINT_GROUP = "harness.metrics"
#: the family a command measures when it is given no metric (``harness compare``), whose metrics come
#: first in results, summaries and tracking
HEADLINE_FAMILY = "3dgs"
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
    #: how far a run's mean may move the wrong way before ``harness track`` calls it a regression
    #: (None: not tracked)
    tolerance: float | None = None

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
    where = f"metric family {name!r}"
    if not callable(compute) or (prepare is not None and not callable(prepare)):
        raise RegistrationError(where, "compute (and prepare, when given) must be callable")
    fam = MetricFamily(name, compute, prepare)
    old = FAMILIES.get(name)
    if old is not None and _code(old.compute, old.prepare) != _code(compute, prepare):
        raise RegistrationError(where, "the name is already registered")
    FAMILIES[name] = fam
    plugins.registered(where, lambda: FAMILIES.pop(name, None))
    return fam


def _code(*fns) -> tuple:
    """Which code the functions are (module, qualified name): a module imported twice registers the same."""
    return tuple(None if f is None else (getattr(f, "__module__", None), getattr(f, "__qualname__", None))
                 for f in fns)


_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]*")


def _callable(where: str, field: str, fn, optional: bool = True) -> None:
    if not (fn is None and optional) and not callable(fn):
        raise RegistrationError(where, f"{field} must be a function, got {type(fn).__name__}")


def _checked_fields(name, compute, higher_is_better, cost, valid_range, family, label, digits, unit, masks,
                    prepare, check, with_metric, tolerance) -> tuple[float, float]:
    """Every field of a registration checked; a wrong one is a RegistrationError naming it. Returns
    the valid range as floats."""
    where = f"metric {name!r}"
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise RegistrationError(where, "the name must be letters, digits and _ . + - (it becomes a results column "
                                       "and a word of --metrics)")
    _check_values(where, higher_is_better, cost, digits, tolerance)
    _check_texts(where, name, family, label, unit, masks, with_metric)
    _check_functions(where, compute, family, prepare, check)
    try:
        lo, hi = (float(x) for x in valid_range)
    except (TypeError, ValueError):
        raise RegistrationError(where, f"valid_range must be two numbers (low, high), got {valid_range!r}") from None
    if not lo <= hi:
        raise RegistrationError(where, f"valid_range {valid_range!r} is empty")
    return lo, hi


def _check_values(where: str, higher_is_better, cost, digits, tolerance) -> None:
    if not isinstance(higher_is_better, bool):
        raise RegistrationError(where, f"higher_is_better must be True or False, got {higher_is_better!r}")
    if cost not in PASS_KINDS:
        raise RegistrationError(where, f"cost must be one of {', '.join(PASS_KINDS)}, got {cost!r}")
    if isinstance(digits, bool) or not isinstance(digits, int) or not 0 <= digits <= 12:
        raise RegistrationError(where, f"digits must be a whole number of decimals from 0 to 12, got {digits!r}")
    number = not isinstance(tolerance, bool) and isinstance(tolerance, (int, float))
    if tolerance is not None and not (number and math.isfinite(tolerance) and tolerance >= 0):
        raise RegistrationError(where, f"tolerance must be a finite number >= 0 or None, got {tolerance!r}")


def _check_texts(where: str, name: str, family, label, unit, masks, with_metric) -> None:
    for field_name, value in (("family", family), ("label", label), ("unit", unit)):
        if not isinstance(value, str):
            raise RegistrationError(where, f"{field_name} must be text, got {value!r}")
    if not family or not _NAME.fullmatch(family):
        raise RegistrationError(where, f"family must be a name (letters, digits and _ . + -), got {family!r}")
    if name.startswith(GT_PREFIX) != (family == GT_FAMILY):
        raise RegistrationError(where, f"a name starting with {GT_PREFIX!r} is a metric against the photo: it and "
                                       f"only it has family {GT_FAMILY!r}")
    for field_name, value in (("masks", masks), ("with_metric", with_metric)):
        if value is not None and not isinstance(value, str):
            raise RegistrationError(where, f"{field_name} must be a metric name or None, got {value!r}")


def _check_functions(where: str, compute, family: str, prepare, check) -> None:
    _callable(where, "prepare", prepare)
    _callable(where, "check", check)
    if compute is None:
        if family not in FAMILIES and family != GT_FAMILY:
            raise RegistrationError(where, f"compute is missing: give compute=, or register family {family!r}'s "
                                           "joint computer first (register_family)")
        return
    _callable(where, "compute", compute, optional=False)
    try:
        inspect.signature(compute).bind(None, None)
    except TypeError:
        raise RegistrationError(where, "compute must take two images: compute(reference, test)") from None
    except ValueError:  # a builtin without a signature: taken as it is
        pass


def register_metric(name: str, compute: Callable | None = None, *, higher_is_better: bool, cost: str = "psnr",
                    valid_range: tuple[float, float] = (-math.inf, math.inf), needs_alpha: bool = False,
                    family: str = "other", label: str | None = None, digits: int = 3, unit: str = "",
                    doc: str = "", inf_if_identical: bool = False, masks: str | None = None,
                    prepare: Callable | None = None, check: Callable | None = None,
                    with_metric: str | None = None, tolerance: float | None = None) -> MetricSpec:
    """Register metric ``name`` (module docstring) and its ``gt_`` twin; returns its spec.

    "A minimal metric is ``register_metric(name, compute, higher_is_better=…)`` — every other field has
    a sound default (cost 'like a PSNR pass' or measured, unbounded range)": the cost is a PSNR pass
    unless given, not measured — measuring would run the metric at registration, and registering
    must stay cheap (a plugin is imported by every command that lists its group)."""
    lo, hi = _checked_fields(name, compute, higher_is_better, cost, valid_range, family,
                             name if label is None else label, digits, unit, masks, prepare, check, with_metric,
                             tolerance)
    spec = MetricSpec(name, label or name, higher_is_better, digits, family, str(doc), compute, (lo, hi),
                      bool(inf_if_identical), cost, bool(needs_alpha), unit, masks, prepare, check, with_metric,
                      None if tolerance is None else float(tolerance))
    METRICS.add(name, spec, same=lambda a, b: a.identity() == b.identity())
    twin = GT_PREFIX + name
    if family != GT_FAMILY and not METRICS.registered(twin):  # a photo metric of that name stays
        gt = replace(spec, name=twin, label=f"{spec.label} vs photo", family=GT_FAMILY, tolerance=None,
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


def headline() -> tuple[str, ...]:
    """The metrics of :data:`HEADLINE_FAMILY` (PSNR, SSIM, LPIPS), registry order."""
    return family_names(HEADLINE_FAMILY)


def tracked() -> list[MetricSpec]:
    """The metrics ``harness track`` compares (those registered with a ``tolerance``), registry order."""
    return [m for m in METRICS if m.tolerance is not None]


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
