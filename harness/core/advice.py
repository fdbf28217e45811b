"""Warnings a command prints once per process: ``harness: warning: <message>`` on stderr.

A parameter set the checks accept but a user should hear about (:meth:`harness.core.params.Params.advisories`)
is announced where a command resolves it — a config's method entry, ``harness prune``'s flags, a call of
``harness.prune`` — and only once however many times it is resolved again. An advisory the method's own
defaults already carry is not announced: it is a property of that method, said in its documentation
(e.g. ``betadesc-vr`` keeps the reading its virtual-rig weight was selected on), not a choice the user made.
"""

from __future__ import annotations

import sys

_SAID: set[str] = set()


def warn_once(message: str) -> bool:
    """Print ``message`` as one ``harness: warning:`` line unless this process already did; True if printed."""
    if message in _SAID:
        return False
    _SAID.add(message)
    print(f"harness: warning: {message}", file=sys.stderr, flush=True)
    return True


def announce(what: str, params) -> None:
    """Each advisory of ``params`` (a :class:`~harness.core.params.Params`) that its class's defaults do not
    carry too, once, prefixed by ``what``."""
    own = set(type(params)().advisories())
    for line in params.advisories():
        if line in own:
            continue
        warn_once(f"{what}: {line}")
