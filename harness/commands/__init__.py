"""Sub-commands of `harness`, one module each (discovered by :mod:`harness.cli`).

:func:`catalog` lists a package's command modules (or benchmark modules) with their ``NAME`` and
``HELP`` read from the source, without running it: ``harness --help`` and ``harness bench --help``
name every command, but import none of them (nor the libraries they import), and ``harness NAME``
imports only that command's module, ``harness/commands/NAME.py`` (a module's ``NAME`` is its file
name).
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import pkgutil
from dataclasses import dataclass
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


def _declared(origin: str | None) -> tuple[str, str] | None:
    """``(NAME, HELP)`` when both are module-level string constants in the source file ``origin``."""
    if not origin or not origin.endswith(".py"):
        return None
    found = {}
    for node in ast.parse(Path(origin).read_bytes(), origin).body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name) \
                and node.targets[0].id in ("NAME", "HELP"):
            try:
                found[node.targets[0].id] = ast.literal_eval(node.value)
            except ValueError:  # computed: the module is imported instead
                return None
    return (found["NAME"], found["HELP"]) if all(isinstance(found.get(k), str) for k in ("NAME", "HELP")) else None


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

