"""Run-config sections as dataclasses of typed ``config_param(...)`` fields, read by one function.

A section (``protocol:``, a scene, a ``methods[]`` entry, the top level) is a frozen dataclass whose
fields are declared with :func:`config_param` — a pruner parameter's declaration
(:func:`harness.core.params.param`: one default, a doc, bounds (``ge``/``le``), ``choices`` (a tuple,
or a function returning registered names) or, for a value that is no scalar, ``parse(value, key,
source)``) and what the value changes (``changes``: the cache keys that hold it,
:mod:`harness.run.config.keys`). :func:`read_section`
checks a YAML mapping against it: unknown keys (with "did you mean"), then every given key by its
declaration. Every problem is one :class:`~harness.core.errors.InputError` naming the config file
and the key path (``protocol.longest_side: 99999 is outside [8, 8192]``).
"""

from __future__ import annotations

import dataclasses
import types
import typing

from harness.core.params import param
from harness.run.config.checks import boolean, choice, num, only, string


def config_param(default, *, changes, doc: str, **checks) -> dataclasses.Field:
    """A run-config field: :func:`~harness.core.params.param` (``doc`` and ``checks``: ``ge``, ``le``,
    ``choices``, ``parse`` ...) and what its value ``changes`` — ``()`` no result, ``"content"`` the
    files it names, or the cache keys that hold it (:data:`harness.run.config.keys.KEYS`). Required:
    a field cannot leave the question open."""
    f = param(default, doc=doc, **checks)
    return dataclasses.field(default=f.default, metadata={**f.metadata, "changes": changes})


def declared(cls) -> list[dataclasses.Field]:
    """The fields of section ``cls`` declared with ``param`` (others are filled by the reader)."""
    return [f for f in dataclasses.fields(cls) if "doc" in f.metadata]


def default_of(f: dataclasses.Field):
    return f.default_factory() if f.default is dataclasses.MISSING else f.default


def _base(hint) -> tuple[type, bool]:
    """(type, optional) of a field's type hint."""
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        return (args[0] if len(args) == 1 else object), len(args) < len(typing.get_args(hint))
    return hint, False


def convert(f: dataclasses.Field, hint, value, key: str, src: str):
    """``value`` read by field ``f``'s declaration (module docstring)."""
    m = f.metadata
    if m.get("parse") is not None:
        return m["parse"](value, key, src)
    kind, optional = _base(hint)
    if value is None and optional:
        return None
    if kind is bool:
        return boolean(value, key, src)
    if kind in (int, float):
        v = num(value, key, src, lo=m.get("ge"), hi=m.get("le"), integer=kind is int)
        return float(v) if kind is float else v
    choices = m.get("choices")
    if choices is not None:
        return choice(value, choices() if callable(choices) else choices, key, src)
    if kind is str:
        return string(value, key, src)
    raise TypeError(f"{key}: declare how to read a {hint!r} (parse=)")


def read_section(cls, d: dict, where: str, src: str, *, defaults: dict | None = None, extra=()) -> dict:
    """The declared fields of ``cls`` from mapping ``d`` (keys beyond them and ``extra`` refused):
    each given value read by its declaration, each absent one from ``defaults``, else its default."""
    fields = declared(cls)
    only(d, {f.name for f in fields} | set(extra), where or "top level", src)
    hints = typing.get_type_hints(cls)
    out = {}
    for f in fields:
        key = f"{where}.{f.name}" if where else f.name
        if f.name in d:
            out[f.name] = convert(f, hints[f.name], d[f.name], key, src)
        elif defaults is not None and f.name in defaults:
            out[f.name] = defaults[f.name]
        else:
            out[f.name] = default_of(f)
    return out
