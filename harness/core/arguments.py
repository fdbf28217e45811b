"""Typed checks of the Python API's arguments, with the command line's rules: each returns the value
as the harness uses it or raises :class:`~harness.core.errors.InputError` naming the argument.

The command line's parser only ever hands over ``int`` or ``float``; Python callers can hand over
anything, and Python converts too eagerly (``bool`` is an ``int``, ``int(1.5)`` is 1, ``'256' <= 8192``
is a TypeError). So:

* a **whole number** (a seed, a size in pixels, a count of views or workers) is an ``int`` or a numpy
  integer — never a ``bool``, never a ``float`` even when integral (``seed=1.5`` and ``longest_side=1.5``
  were accepted as 1 and 1 px), never text;
* a **number** (a ratio, an aspect) is an ``int`` or ``float`` (numpy's too), finite, never a ``bool``
  (``ratio=True`` removed every splat) or text.
"""

from __future__ import annotations

import math

import numpy as np

from harness.core.errors import InputError


def _range_text(lo, hi, interval: bool = False) -> str:
    if lo is not None and hi is not None:
        return f" in [{lo:g}, {hi:g}]" if interval else f" from {lo} to {hi}"
    return f" >= {lo}" if lo is not None else f" <= {hi}" if hi is not None else ""


def _given(value) -> str:
    return f"{value!r} ({type(value).__name__})"


def whole(value, name: str, lo: int | None = None, hi: int | None = None) -> int:
    """``value`` as an int within [lo, hi] (module docstring), else InputError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise InputError(name, f"must be a whole number{_range_text(lo, hi)}, got {_given(value)}")
    v = int(value)
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        raise InputError(name, f"must be a whole number{_range_text(lo, hi)}, got {v}")
    return v


def number(value, name: str, lo: float | None = None, hi: float | None = None) -> float:
    """``value`` as a finite float within [lo, hi] (module docstring), else InputError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(name, f"must be a number{_range_text(lo, hi, True)}, got {_given(value)}")
    v = float(value)
    if not math.isfinite(v) or (lo is not None and v < lo) or (hi is not None and v > hi):
        raise InputError(name, f"must be a number{_range_text(lo, hi, True)}, got {value!r}")
    return v


def optional(check, value, name: str, *bounds):
    """``check(value, name, *bounds)``, or None when ``value`` is None (the default applies)."""
    return None if value is None else check(value, name, *bounds)
