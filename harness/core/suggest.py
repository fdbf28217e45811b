"""'Did you mean' for names a user typed: one shared wording for scenes, methods, metrics and keys.

``unknown("scene name", "luigii", ["luigi", "playbot"])`` ->
``"unknown scene name 'luigii' (did you mean 'luigi'?); known: luigi, playbot"``.
Close matches are :func:`difflib.get_close_matches` (ratio >= 0.6), at most three.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable


def close_matches(name: str, known: Iterable[str], n: int = 3) -> list[str]:
    """Up to ``n`` known names close to ``name`` (case-insensitive), best first."""
    known = list(dict.fromkeys(str(k) for k in known))
    lower = {k.lower(): k for k in known}
    return [lower[m] for m in difflib.get_close_matches(str(name).lower(), list(lower), n=n, cutoff=0.6)]


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"``, ``" (did you mean 'x' or 'y'?)"`` or ``""``."""
    close = close_matches(name, known)
    if not close:
        return ""
    quoted = [f"'{c}'" for c in close]
    return f" (did you mean {' or '.join([', '.join(quoted[:-1]), quoted[-1]] if len(quoted) > 1 else quoted)}?)"


def unknown(what: str, name: str, known: Iterable[str]) -> str:
    """One line: ``unknown <what> '<name>' (did you mean ...?); known: a, b, c``."""
    known = list(known)
    return f"unknown {what} '{name}'{did_you_mean(name, known)}; known: {', '.join(map(str, known))}"
