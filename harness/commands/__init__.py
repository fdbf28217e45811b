"""Sub-commands of `harness`, one module each (discovered by :mod:`harness.cli`).

:func:`catalog` lists a package's command modules (or benchmark modules) with their ``NAME`` and
``HELP`` read from the source, without running it: ``harness --help`` and ``harness bench --help``
name every command, but import none of them (nor the libraries they import), and ``harness NAME``
imports only that command's module, ``harness/commands/NAME.py`` (a module's ``NAME`` is its file
name). :func:`plugin_catalog` lists the modules installed packages add through an entry-point group
(``harness bench``'s: ``harness.benchmarks``), read the same way.
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import pkgutil
import sys
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path


def help_text(text: str) -> str:
    """``text`` for argparse, which %-formats help strings: a literal "%" (as in "30 %") is doubled."""
    return str(text).replace("%", "%%")


@dataclass(frozen=True)
class Entry:
    """A discovered command (or benchmark) module: its dotted name, ``NAME`` and ``HELP``."""

    module: str
    name: str
    help: str

    def load(self):
        """The module itself (imported now, with whatever it imports)."""
        return importlib.import_module(self.module)


def _declared(origin: str | None, names=("NAME", "HELP")) -> tuple[str, ...] | None:
    """The values of ``names`` when each is a module-level string constant in the source file ``origin``."""
    if not origin or not origin.endswith(".py"):
        return None
    found = {}
    for node in ast.parse(Path(origin).read_bytes(), origin).body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name) \
                and node.targets[0].id in names:
            try:
                found[node.targets[0].id] = ast.literal_eval(node.value)
            except ValueError:  # computed: the module is imported instead
                return None
    return tuple(found[k] for k in names) if all(isinstance(found.get(k), str) for k in names) else None


def catalog(package: str) -> list[Entry]:
    """The public modules of ``package`` (names not starting with "_"), sorted by name. A module
    whose ``NAME``/``HELP`` are not literal strings is imported to read them."""
    entries = []
    for info in sorted(pkgutil.iter_modules(importlib.import_module(package).__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = f"{package}.{info.name}"
        declared = _declared(importlib.util.find_spec(module).origin)
        if declared is None:
            mod = importlib.import_module(module)
            declared = (mod.NAME, mod.HELP)
        entries.append(Entry(module, *declared))
    return entries



def plugin_catalog(group: str, taken=()) -> list[Entry]:
    """The modules installed packages add through entry-point group ``group``, sorted by name:
    ``mybench = "mypkg.bench"`` under ``[project.entry-points."harness.benchmarks"]`` of a package's
    ``pyproject.toml`` adds ``harness bench mybench``, whose module defines ``HELP``, ``add_arguments``
    and ``run`` as a built-in's does (its ``HELP`` read from the source when it is a literal string).
    The entry point's name is the sub-command's. A name a built-in (``taken``) or an earlier entry
    point holds, and a module that cannot be found, are skipped with one warning line on stderr."""
    entries, seen = [], set(taken)
    for ep in sorted(entry_points(group=group), key=lambda e: (e.name, e.value)):
        where = f"{ep.name} = {ep.value} ({group})"
        if ep.name in seen:
            print(f"harness: warning: entry point {where} skipped: the name is taken", file=sys.stderr)
            continue
        try:
            spec = importlib.util.find_spec(ep.module)
        except (ImportError, ValueError):
            spec = None
        if spec is None:
            print(f"harness: warning: entry point {where} skipped: no module {ep.module}", file=sys.stderr)
            continue
        declared = _declared(spec.origin, ("HELP",))
        entries.append(Entry(ep.module, ep.name, declared[0] if declared else importlib.import_module(ep.module).HELP))
        seen.add(ep.name)
    return entries
