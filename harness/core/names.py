"""Names as file names: :func:`file_name`, the one map from a scene, method, variant or label to the
name of a file or folder (``images/<scene>/``, ``contact_sheets/<scene>.png``, ``plots/curves_<scene>.png``,
``<method>__<variant>__r<ratio>.png``, the report page's anchors), and the checks every name of a config
passes before any work (:func:`name_problem`, :func:`collisions`).

:func:`file_name` is **one to one**: a name that is already a plain file name — ASCII letters, digits,
``.``, ``_``, ``-``, starting with a letter or digit, no ``__`` (the separator of render file names), at
most :data:`PLAIN_MAX` characters — is itself; any other name is its plain characters (each run of
others, and of ``_``, as one ``_``, cut to :data:`READABLE_MAX`), then ``~`` and the first 12 hex digits
of its SHA-256. ``~`` is never in a plain name, so an escaped name never equals a plain one, and two
escaped names differ by their digests (a collision is a 48-bit accident). So ``x/y`` is
``x_y~…`` beside ``x_y``; ``..`` is ``_~…``, never ``.`` or ``..``; a 300-character name is 41 characters.
What it cannot make distinct is case on a case-insensitive file system (``A`` and ``a``): that, like
everything else about a config's names, is :func:`collisions`' to refuse.

Names are checked where a config is read ("all names are checked at config load (collisions, length,
control characters), before any work"): at most :data:`NAME_MAX` characters, no control or format
character (an escape sequence in a scene name was printed raw to the terminal), and no two names whose
files would be one on a case-insensitive file system.
"""

from __future__ import annotations

import hashlib
import re
import unicodedata

#: the longest name a config may give a scene, variant or label
NAME_MAX = 128
#: the longest name kept as it is in a file name
PLAIN_MAX = 64
#: how much of an escaped name's own characters its file name keeps (before ``~`` and the digest)
READABLE_MAX = 28
_PLAIN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")
_NOT_PLAIN = re.compile(r"[^A-Za-z0-9.-]+")


def file_name(name) -> str:
    """The file name of ``name`` (module docstring): itself when plain, else an escaped form."""
    text = str(name)
    if len(text) <= PLAIN_MAX and _PLAIN.fullmatch(text) and "__" not in text:
        return text
    readable = _NOT_PLAIN.sub("_", text).lstrip(".")[:READABLE_MAX] or "_"
    return f"{readable}~{hashlib.sha256(text.encode('utf-8', 'surrogatepass')).hexdigest()[:12]}"


def _control(ch: str) -> bool:
    """A character a terminal acts on or hides: control (C0, C1: ESC, NUL, …), format (bidi
    overrides, zero width), line and paragraph separators, surrogates and unassigned code points."""
    return unicodedata.category(ch) in ("Cc", "Cf", "Cs", "Co", "Cn", "Zl", "Zp")


def name_problem(name: str) -> str | None:
    """Why ``name`` cannot name a scene, variant or label (module docstring), or None."""
    bad = next((ch for ch in name if _control(ch)), None)
    if bad is not None:
        return f"{name!r} holds the control character U+{ord(bad):04X}; names are printed and become file names"
    if len(name) > NAME_MAX:
        return f"is {len(name)} characters long; names have at most {NAME_MAX}"
    return None


def collisions(named: list[tuple[str, str]]) -> tuple[str, str] | None:
    """The first two places (``where``, from ``named`` = [(where, name)]) whose distinct names would
    share a file on a case-insensitive file system, or None."""
    seen: dict[str, tuple[str, str]] = {}
    for where, name in named:
        key = file_name(name).casefold()
        if key in seen and seen[key][1] != name:
            return seen[key][0], where
        seen.setdefault(key, (where, name))
    return None
