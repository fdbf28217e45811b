"""A small lazy registry (the pattern of timm's ``register_model`` and lm-evaluation-harness).

A registry maps names to entries (a pruner's, a renderer's or a metric's spec with its metadata).
Entries come from

* built-in modules, imported the first time a name is looked up or the list is asked for (so the
  modules must be cheap to import: heavy libraries are imported inside the functions that use them);
* third-party packages, through an entry-point group: each entry point names a module whose import
  registers its entries (``myname = "mypkg.pruners"`` under ``[project.entry-points."harness.pruners"]``).
  Entry points are loaded only when a name is not built in, or when the whole list is asked for, and
  each is a guest (:mod:`harness.core.plugins`): one that fails to import, exits, or takes a name a
  built-in or an earlier plugin holds is skipped with a warning, and everything it registered is
  taken back.

A registration the registry refuses is a :class:`RegistrationError`: one line naming the entry and
the field (``metric 'mae': cost must be one of lpips, ssim, psnr, got 'gpu'``).
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Iterator
from typing import Generic, TypeVar

from harness.core import plugins
from harness.core.errors import HarnessError

T = TypeVar("T")


class RegistrationError(HarnessError, ValueError):
    """A registration that cannot be accepted: ``<kind> '<name>': <what is wrong with which field>``
    (``RegistrationError("metric 'mae'", "cost must be ...")``)."""


def _initializing(module: str) -> bool:
    """Is ``module`` being imported right now (its body running)?"""
    spec = getattr(sys.modules.get(module), "__spec__", None)
    return bool(getattr(spec, "_initializing", False))


class Registry(Generic[T]):
    """``modules``: the built-in modules whose import registers the built-in entries (the registry's
    own module too when it registers them itself); ``group``: the entry-point group of plugins."""

    def __init__(self, kind: str, *, modules: tuple[str, ...] = (), group: str | None = None):
        self.kind, self.modules, self.group = kind, modules, group
        self._entries: dict[str, T] = {}
        self._guests: dict[str, plugins.Visit] = {}  # name -> the plugin that registered it
        self._builtins_loaded = False
        self._plugins_loaded = False

    def add(self, name: str, entry: T, *, same=lambda a, b: False) -> None:
        """Register ``entry`` under ``name``; another entry under a taken name is a
        :class:`RegistrationError` (``same(old, new)`` tells a harmless re-registration, e.g. a
        module imported twice). Inside a plugin's visit, the built-ins are loaded first (a plugin
        never takes a built-in's name) and the registration is journalled to the plugin."""
        guest = plugins.current()
        if guest is not None and any(map(_initializing, self.modules)):
            guest = None  # a built-in module that the plugin imported: its registrations are built-ins
        if guest is not None:
            self._load_builtins()
        old = self._entries.get(name)
        if old is not None:
            if same(old, entry):
                return
            holder = self._guests.get(name)
            raise RegistrationError(f"{self.kind} {name!r}", f"the name is taken by the plugin {holder.who}" if holder
                                    else "the name is taken by a built-in, which a plugin cannot replace"
                                    if guest is not None else "the name is already registered")
        self._entries[name] = entry
        if guest is not None:
            self._guests[name] = guest
            plugins.registered(f"{self.kind} {name!r}", lambda: self._remove(name))

    def _remove(self, name: str) -> None:
        self._entries.pop(name, None)
        self._guests.pop(name, None)

    def registered(self, name: str) -> bool:
        """Is ``name`` registered already (nothing is loaded to find out)?"""
        return name in self._entries

    def origin(self, name: str) -> plugins.Visit | None:
        """The plugin that registered ``name`` (None: a built-in, or registered by the caller's code)."""
        return self._guests.get(name)

    def _load_builtins(self) -> None:
        if not self._builtins_loaded:
            self._builtins_loaded = True
            with plugins.host():
                for mod in self.modules:
                    importlib.import_module(mod)

    def _load_plugins(self) -> None:
        if not self._plugins_loaded and self.group:
            self._plugins_loaded = True
            plugins.visit_group(self.group)

    def get(self, name: str) -> T:
        """The entry ``name``; ``KeyError`` with the known names otherwise."""
        self._load_builtins()
        if name not in self._entries:
            self._load_plugins()
        try:
            return self._entries[name]
        except KeyError:
            from harness.core.suggest import unknown

            raise KeyError(unknown(self.kind, name, self.names())) from None

    def names(self) -> list[str]:
        return list(self._all())

    def _all(self) -> dict[str, T]:
        self._load_builtins()
        self._load_plugins()
        return self._entries

    def __iter__(self) -> Iterator[T]:
        """Entries in registration order (built-ins first)."""
        return iter(list(self._all().values()))

    def __contains__(self, name: str) -> bool:
        try:
            self.get(name)
        except KeyError:
            return False
        return True
