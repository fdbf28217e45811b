"""The run-config reference, ``docs/config.md``, generated from the sections' declarations.

Each section's table lists its keys with the type, range or choices, default, meaning and what the
value changes (:mod:`harness.run.config.keys`), all read from the ``config_param(...)`` declarations of
:mod:`harness.run.config.sections` and :mod:`harness.run.config.executor`; ``harness config schema``
prints it, and a test compares it with ``docs/config.md``.
"""

from __future__ import annotations

import dataclasses
import types
import typing

from harness.run.config.executor import ExecutorSpec
from harness.run.config.keys import CONTENT, KEYS, changes_of
from harness.run.config.schema import declared, default_of
from harness.run.config.sections import CameraSpec, MethodEntry, Protocol, SceneSpec, Settings

#: (heading, what to know beyond the table, the key path it documents, section), in a config's order
SECTIONS = (
    ("Top level", "Besides the sections below (`scenes` and `methods` required), `protocols` and `extends`:", "",
     Settings),
    ("`protocol:`", "How every scene is evaluated.", "protocol.", Protocol),
    ("`scenes:`", "One entry per scene, a mapping or just its name: `name` (required; also the dataset name or "
                  "path when `source` is absent), `label` (its name in the tables; default: the name) and:",
     "scenes[].", SceneSpec),
    ("`scenes[].cameras:`", "Views from a cameras file instead of a rig (`path` required).", "scenes[].cameras.",
     CameraSpec),
    ("`methods:`", "One entry per pruner, a mapping or just its name (`name` required).", "methods[].",
     MethodEntry),
    ("`executor:`", "Where the work runs: a name, or a mapping.", "executor.", ExecutorSpec),
)

INTRO = """\
# Run config reference

A run config is a YAML mapping read by `harness run CONFIG.yaml` (and `plan`, `config show`); every
key below is optional unless its section says otherwise, and a key the reference does not list is
refused with "did you mean". `extends: other.yaml` makes a config another one with its own keys over
it (mappings merge key by key, lists and values replace); `harness config show CONFIG` prints the
resolved config with the file and line of every value. Paths and names accept `${VAR}` and
`${VAR:-default}`. Every problem is one line naming the file and the key path
(`methods[2].sweep.voxel: ...`), exit status 2.

*Changes* says what a value changes, and so which cached stage results a new value recomputes:
"—" none (a label, a folder, a schedule), "content" the files it names (by their sha256, never by
name), else the cache keys that hold it. It is declared with the field, and the keys are derived from
the declarations, so a field cannot be left out of a key.

Generated from the declarations by `harness config schema`; do not edit by hand.
"""

OUTRO = """\
## `protocols:` and the rest

`protocols: [rig, shifted, independent, real]` lists the held-out view protocols (the first is the
primary one, whose views the tables name without a suffix); an entry is a name or a mapping with the
protocol's parameters (`{name: real, n_test: 8}`). `methods[].sweep: {key: [values]}` expands an
entry into one variant per combination, named `k1=v1,k2=v2` in the order written (prefixed by its
`variant` when given); a plain entry's variant is its `variant`, else `default`.

## Keys

| key | what it versions |
|---|---|
"""


def _type(hint) -> str:
    """``int``, ``float or none``, ``list of str``, ``3 numbers`` ... of a field's type hint."""
    optional = ""
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        optional = " or none" if len(args) < len(typing.get_args(hint)) else ""
        hint = args[0] if len(args) == 1 else hint
        if len(args) > 1:
            return " or ".join(_type(a) for a in args) + optional
    args = typing.get_args(hint)
    if typing.get_origin(hint) is tuple:
        inner = "number" if args[0] is float else getattr(args[0], "__name__", str(args[0]))
        return (f"list of {inner}" if len(args) == 2 and args[1] is Ellipsis else f"{len(args)} {inner}s") + optional
    if dataclasses.is_dataclass(hint) or hint is dict:
        return "mapping" + optional
    return ("true/false" if hint is bool else getattr(hint, "__name__", str(hint))) + optional


def _range(m: dict) -> str:
    parts = [f"{op} {m[k]:g}" for k, op in (("ge", "≥"), ("gt", ">"), ("le", "≤"), ("lt", "<"))
             if m.get(k) is not None]
    choices = m.get("choices")
    if choices is not None:
        parts.append("a registered name" if callable(choices) else "one of " + ", ".join(map(str, choices)))
    return ", ".join(parts)


def _default(f) -> str:
    registered = getattr(f.metadata.get("parse"), "registered", None)
    return f"every registered {registered}" if registered else f"`{_value(default_of(f))}`"


def _value(v) -> str:
    if v is None:
        return "none"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return format(v, "g") if isinstance(v, float) else str(v)


def _changes(f) -> str:
    declared_ = changes_of(f)
    return ", ".join(k if k == CONTENT else f"`{k}`" for k in declared_) or "—"


def section_table(prefix: str, cls) -> str:
    """The markdown table of one section's declared fields."""
    hints = typing.get_type_hints(cls)
    rows = ["| key | type | range | default | changes | meaning |", "|---|---|---|---|---|---|"]
    for f in declared(cls):
        t = _type(hints[f.name])
        cells = [f"`{prefix}{f.name}`", t, _range(f.metadata), _default(f), _changes(f),
                 f.metadata["doc"].replace("|", "\\|")]
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join(rows)


def reference() -> str:
    """``docs/config.md``: every section's table, then the protocols and the keys."""
    parts = [INTRO]
    for heading, note, prefix, cls in SECTIONS:
        parts.append(f"## {heading}\n\n" + (f"{note}\n\n" if note else "") + f"{section_table(prefix, cls)}\n")
    parts.append(OUTRO + "\n".join(f"| `{k}` | {layout.doc} |" for k, layout in KEYS.items()) + "\n")
    return "\n".join(parts)
