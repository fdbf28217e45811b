"""Checks of YAML config values: each returns the value or raises a one-line
:class:`~harness.core.errors.InputError` naming the file (``src``) and the key (``where``)."""

from __future__ import annotations

import math
import os
import re

from harness.core.errors import InputError
from harness.core.suggest import unknown

_ENV = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)(?::-([^}]*))?\}")


def expand_env(text: str) -> str:
    """Expand ``${VAR}`` and ``${VAR:-default}`` (shell semantics: default when unset or empty)."""
    return _ENV.sub(lambda m: os.environ.get(m.group(1)) or (m.group(2) or ""), text)



def mapping(value, where: str, src: str) -> dict:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise InputError(src, f"{where}: expected a mapping, got {type(value).__name__}")
    return value


def only(d: dict, allowed: set[str], where: str, src: str) -> None:
    extra = sorted(set(d) - allowed, key=str)
    if extra:
        raise InputError(src, f"{where}: " + "; ".join(unknown("key", k, sorted(allowed)) for k in extra))


def num(v, where: str, src: str, *, lo=None, hi=None, integer=False):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or (integer and not isinstance(v, int)):
        raise InputError(src, f"{where}: expected {'an integer' if integer else 'a number'}, got {v!r}")
    if not math.isfinite(v):
        raise InputError(src, f"{where}: expected a finite number, got {v!r}")
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        raise InputError(src, f"{where}: {v!r} is outside [{lo}, {hi}]")
    return v


def boolean(v, where: str, src: str) -> bool:
    if not isinstance(v, bool):
        raise InputError(src, f"{where}: expected true or false, got {v!r}")
    return v


def string(v, where: str, src: str) -> str:
    if not isinstance(v, str) or not v.strip():
        raise InputError(src, f"{where}: expected a non-empty string, got {v!r}")
    return v


def choice(v, choices, where: str, src: str, what: str = "value") -> str:
    """``v`` if it is one of ``choices``, else an InputError with the close ones ("did you mean")."""
    if v not in choices:
        raise InputError(src, f"{where}: {unknown(what, v, choices)}")
    return v


def fractions(v, where: str, src: str) -> tuple[float, ...]:
    if not isinstance(v, list) or not v:
        raise InputError(src, f"{where}: expected a non-empty list of fractions in [0, 1]")
    return tuple(float(num(x, f"{where}[{i}]", src, lo=0.0, hi=1.0)) for i, x in enumerate(v))


def names(v, choices, where: str, src: str, what: str = "name") -> tuple[str, ...]:
    if not isinstance(v, list):
        raise InputError(src, f"{where}: expected a list of names from {', '.join(choices)}")
    return tuple(choice(x, choices, f"{where}[{i}]", src, what) for i, x in enumerate(v))
