"""What a run config's values put in the stage cache's keys, derived from what each field declares.

Every field of a run-config section (:mod:`harness.run.config.sections`) declares what its value
changes, ``config_param(..., changes=...)`` (:mod:`harness.run.config.schema`):

* ``()``: no result (a label, the output folder, the worker count, which tables are written ...);
* :data:`CONTENT`: it names files (a scene, a cameras file, a capture), and those enter every key
  they change by the sha256 of their content, never by their name;
* the names of the keys its value enters (:data:`KEYS`).

:func:`key_inputs` gathers, for one key, the values of the fields of the given sections that declare
it: a new field is in the keys it declares from its first run, and a field that declares nothing is
refused the first time a key is derived (:func:`changes_of`), never a stale cache entry. The values
are laid out as the keys were when they were listed by hand (:class:`Layout`: the view keys hold them
under ``source``, a sequence's width and height as ``size``), so existing entries keep their keys.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from harness.run.config.schema import declared

#: ``changes=CONTENT``: the files the value names enter the keys by their content
CONTENT = "content"


@dataclass(frozen=True)
class Layout:
    """A key's inputs from the config: what they version (``doc``), and where they sit in the key —
    under ``nest`` (all of them but ``top``), with ``lists`` gathering several fields' values into
    one list (``size: [width, height]``)."""

    doc: str
    nest: str | None = None
    top: tuple[str, ...] = ()
    lists: dict[str, tuple[str, ...]] = field(default_factory=dict)


#: every key a config field can declare, in the order of the stages
KEYS = {
    "load": Layout("the scene digest, held by every stage's key (with the sha256 of the scene's files)"),
    "rig_views": Layout("a synthetic rig's views of a scene", nest="source", top=("longest_side",)),
    "file_views": Layout("a cameras file's views of a scene", nest="source", top=("longest_side",)),
    "protocol_views": Layout("a view protocol's held-out views of a scene, where the protocol caches them",
                             nest="source", top=("longest_side",)),
    "sequence_views": Layout("an MPEG sequence's views", nest="source", lists={"size": ("width", "height")}),
    "score": Layout("a pruner's scores"),
    "aware_score": Layout("a camera-aware pruner's scores (the key of one that ignores cameras holds none)"),
    "prune": Layout("the pruned set of a score at a ratio"),
    "render_ref": Layout("the unpruned render of a view"),
    "metrics": Layout("the metrics of a pruned render against the unpruned one"),
    "gt": Layout("the unpruned render against a view's photo"),
}


def changes_of(f: dataclasses.Field) -> tuple[str, ...]:
    """What field ``f`` declares it changes: ``()``, ``(CONTENT,)`` or key names of :data:`KEYS`.
    A field that declares nothing, or a key no stage builds, is a ``TypeError`` naming it."""
    declared = f.metadata.get("changes")
    if declared is None:
        raise TypeError(f"config field {f.name!r}: declare what it changes, config_param(..., changes=...): "
                        f"() for no result, {CONTENT!r} for files by content, or keys of {', '.join(KEYS)}")
    declared = (declared,) if isinstance(declared, str) else tuple(declared)
    unknown = [k for k in declared if k != CONTENT and k not in KEYS]
    if unknown:
        raise TypeError(f"config field {f.name!r}: changes={unknown[0]!r} is no key ({', '.join(KEYS)})")
    return declared


def key_inputs(key: str, *sections, unset: bool = False) -> dict:
    """The values of every field of ``sections`` (section instances) that declares ``key``, laid out
    as :data:`KEYS` says; ``unset``: the same names, each ``None`` (a key that holds the field's name
    but not its value: a pruner that ignores cameras ignores ``protocol.device``)."""
    layout = KEYS[key]
    flat = {}
    for section in sections:
        for f in declared(section):
            if key in changes_of(f):
                if f.name in flat:
                    raise TypeError(f"config field {f.name!r} declares {key!r} in two sections")
                flat[f.name] = None if unset else getattr(section, f.name)
    for name, parts in layout.lists.items():
        if any(p in flat for p in parts):
            flat[name] = [flat.pop(p, None) for p in parts]
    if layout.nest is None:
        return flat
    return {**{k: v for k, v in flat.items() if k in layout.top},
            layout.nest: {k: v for k, v in flat.items() if k not in layout.top}}
