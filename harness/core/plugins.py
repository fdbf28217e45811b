"""Plugins are guests: a third-party package that fails never takes the host down with it.

A plugin is a module named by an entry point of one of the harness's groups (``harness.pruners``,
``harness.metrics``, ``harness.formats``, ``harness.tables``, ``harness.plots``, ``harness.renderers``,
``harness.protocols``) — ``mae = "mae_metric"`` under ``[project.entry-points."harness.metrics"]`` of
its ``pyproject.toml`` — whose import registers its entries. Importing it is a *visit*
(:func:`visit`):

* anything the import raises — an exception, ``sys.exit``, a registration the registry refuses (a
  wrong field, a name a built-in or an earlier plugin holds: a plugin never shadows one) — skips the
  plugin: whatever it had registered is taken back, one warning names its distribution and entry
  point (logger ``harness.plugins``), and the built-ins go on working;
* ``HARNESS_PLUGINS`` chooses the third-party distributions visited: unset, every installed one;
  ``none``, none; ``a,b``, only those (names compared as PEP 503 normalises them, ``Mae_Metric`` =
  ``mae-metric``), so a user can shut a broken plugin out and a test can shut out whatever else is
  installed. Entry points of the tool's own packages (:data:`HOST_PACKAGES`) are always visited.

:func:`records` lists every visit and its outcome (``harness plugins``); :func:`blame` names the
plugin whose code raised an exception later, while it worked (a plugin pruner failing as it scores).
"""

from __future__ import annotations

import logging
import os
import re
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field
from importlib.metadata import EntryPoint, entry_points

#: every group a plugin can register into, with what it adds (``harness plugins``)
GROUPS = {"harness.pruners": "pruners", "harness.metrics": "metrics", "harness.formats": "scene formats",
          "harness.tables": "tables", "harness.plots": "plots", "harness.renderers": "renderers",
          "harness.protocols": "view protocols"}
ENV = "HARNESS_PLUGINS"
#: the tool's own top-level packages: an entry point into one is the tool's own (always visited), and
#: owns that module only, not the package (:func:`blame`)
HOST_PACKAGES = ("harness", "methods", "renderers")
log = logging.getLogger("harness.plugins")


@dataclass
class Visit:
    """One entry point's visit: who (``group``, ``name = value`` of ``distribution`` ``version``),
    its ``status`` (``loaded`` or ``skipped``), ``reason`` when skipped, and what it registered."""

    group: str
    name: str
    value: str
    distribution: str
    version: str
    status: str = "loading"
    reason: str = ""
    registered: list[str] = field(default_factory=list)
    _undo: list[Callable[[], None]] = field(default_factory=list, repr=False)

    @property
    def who(self) -> str:
        """``mae-metric 0.1.0 (entry point harness.metrics: mae = mae_metric)``."""
        return f"{self.distribution} {self.version} (entry point {self.group}: {self.name} = {self.value})".strip()

    def as_dict(self) -> dict:
        return {"group": self.group, "entry_point": self.name, "module": self.value,
                "distribution": self.distribution, "version": self.version, "status": self.status,
                "reason": self.reason, "registered": list(self.registered)}


_visits: dict[tuple[str, str, str], Visit] = {}
#: the visits under way, innermost last (a plugin's import may load another group's plugins); None
#: marks the host's own code running inside one (built-in modules imported on a guest's behalf)
_current: list[Visit | None] = []


def current() -> Visit | None:
    """The plugin being imported now (its registrations are journalled to it), or None."""
    return _current[-1] if _current else None


@contextmanager
def host():
    """Run the host's own code (built-ins loading) inside a visit: nothing it registers is the guest's."""
    _current.append(None)
    try:
        yield
    finally:
        _current.pop()


def registered(what: str, undo: Callable[[], None]) -> None:
    """Journal a registration made by the plugin being imported (``what``: ``"metric 'mae'"``) with
    how to take it back; outside a visit, nothing to do."""
    visit = current()
    if visit is not None:
        visit.registered.append(what)
        visit._undo.append(undo)


def normalise(name: str) -> str:
    """A distribution name as PEP 503 compares them."""
    return re.sub(r"[-_.]+", "-", str(name)).lower()


def chosen() -> set[str] | None:
    """The distributions ``HARNESS_PLUGINS`` lets in (None: every installed one)."""
    value = os.environ.get(ENV)
    if value is None:
        return None
    names = {normalise(n) for n in value.split(",") if n.strip()}
    return set() if names <= {"none"} else names


def _distribution(ep: EntryPoint) -> tuple[str, str]:
    dist = getattr(ep, "dist", None)
    if dist is None:
        return "?", ""
    return str(dist.metadata["Name"] or dist.name or "?"), str(dist.version or "")


def group_entry_points(group: str) -> list[EntryPoint]:
    """The entry points of ``group`` that ``HARNESS_PLUGINS`` lets in, in a stable order (the host's
    own, whose modules live in :data:`HOST_PACKAGES`, always: they are part of the tool)."""
    allowed = chosen()
    eps = sorted(entry_points(group=group), key=lambda ep: (_distribution(ep)[0].lower(), ep.name, ep.value))
    return [ep for ep in eps if allowed is None or normalise(_distribution(ep)[0]) in allowed
            or _top(ep.value) in HOST_PACKAGES]


def visit_group(group: str) -> list[Visit]:
    """Visit every entry point of ``group`` not visited yet (module docstring); their records."""
    out = []
    for ep in group_entry_points(group):
        key = (group, ep.name, ep.value)
        done = _visits.get(key)
        out.append(done if done is not None and done.status != "loading" else visit(ep, group))
    return out


def visit(ep: EntryPoint, group: str) -> Visit:
    """Import the module of ``ep`` as a guest (module docstring).

    "A plugin that fails to import, raises, calls ``sys.exit``, or shadows a built-in is skipped with
    one warning naming its distribution and entry point": at its import — later, while it works, its
    exception (``sys.exit`` too) is the command's one error line, naming the plugin (:func:`blame`). A
    plugin taking an earlier plugin's name is skipped like one shadowing a built-in: the first keeps it."""
    dist, version = _distribution(ep)
    v = Visit(group, ep.name, ep.value, dist, version)
    _visits[(group, ep.name, ep.value)] = v
    _current.append(v)
    try:
        ep.load()
    except (Exception, SystemExit) as err:  # a guest's failure is its own: KeyboardInterrupt still stops us
        v.status, v.reason = "skipped", _why(err)
        for undo in reversed(v._undo):
            undo()
        log.warning(f"plugin {v.who} skipped: {v.reason}; `harness plugins` lists every plugin")
    else:
        v.status = "loaded"
    finally:
        _current.pop()
        v._undo = []
    return v


def _why(err: BaseException) -> str:
    if isinstance(err, SystemExit):
        return f"it called sys.exit({err.code!r}) while being imported"
    text = " ".join(str(err).split())[:300]
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


def records() -> list[Visit]:
    """Every entry point visited so far, in visiting order."""
    return list(_visits.values())


def _top(value: str) -> str:
    return value.split(":", 1)[0].strip().split(".", 1)[0]


def _home(value: str) -> str:
    """The code a plugin owns: its module's top-level package (``mae_metric``), or the module itself
    when it lives in one of :data:`HOST_PACKAGES`."""
    module = value.split(":", 1)[0].strip()
    top = module.split(".", 1)[0]
    return module if top in HOST_PACKAGES else top


def blame(err: BaseException) -> Visit | None:
    """The loaded plugin whose code raised ``err`` (the innermost frame of code a plugin owns), or None."""
    homes = {_home(v.value): v for v in _visits.values() if v.status == "loaded"}
    tb, found = err.__traceback__, None
    while tb is not None:
        name = str(tb.tb_frame.f_globals.get("__name__", ""))
        found = next((v for home, v in homes.items() if name == home or name.startswith(home + ".")), found)
        tb = tb.tb_next
    return found
