"""A small lazy registry (the pattern of timm's ``register_model`` and lm-evaluation-harness).

A registry maps names to entries (a pruner's, a renderer's or a metric's spec with its metadata).
Entries come from

* built-in modules, imported the first time a name is looked up or the list is asked for (so the
  modules must be cheap to import: heavy libraries are imported inside the functions that use them);
* third-party packages, through an entry-point group: each entry point names a module whose import
  registers its entries (``myname = "mypkg.pruners"`` under ``[project.entry-points."harness.pruners"]``).
  Entry points are loaded only when a name is not built in, or when the whole list is asked for.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from importlib.metadata import entry_points
from typing import Generic, TypeVar

T = TypeVar("T")


class Registry(Generic[T]):
    def __init__(self, kind: str, *, modules: tuple[str, ...] = (), group: str | None = None):
        self.kind, self.modules, self.group = kind, modules, group
        self._entries: dict[str, T] = {}
        self._builtins_loaded = False
        self._plugins_loaded = False

    def add(self, name: str, entry: T, *, same=lambda a, b: False) -> None:
        """Register ``entry`` under ``name``; another entry under a taken name is an error
        (``same(old, new)`` tells a harmless re-registration, e.g. a module imported twice)."""
        old = self._entries.get(name)
        if old is not None and not same(old, entry):
            raise ValueError(f"{self.kind} {name!r} is already registered")
        self._entries[name] = entry

    def registered(self, name: str) -> bool:
        """Is ``name`` registered already (nothing is loaded to find out)?"""
        return name in self._entries

    def _load_builtins(self) -> None:
        if not self._builtins_loaded:
            self._builtins_loaded = True
            for mod in self.modules:
                importlib.import_module(mod)

    def _load_plugins(self) -> None:
        if not self._plugins_loaded and self.group:
            self._plugins_loaded = True
            for ep in entry_points(group=self.group):
                ep.load()  # importing the module runs its registrations

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
        return [e for e in self._all()]

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
