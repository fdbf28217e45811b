"""Typed parameters: a frozen dataclass per pruner, every field with its type, range and meaning.

    @dataclass(frozen=True)
    class MyParams(Params):
        voxel: float = param(0.01, gt=0, le=1, doc="voxel edge as a fraction of the bbox diagonal")
        score: Literal["ucb", "lcb"] = param("ucb", doc="ranking score")
        rounds: int | None = param(None, ge=1, doc="optional cap")

:meth:`Params.parse` checks a mapping (a YAML ``params:`` block) once, at load, and returns the
instance every later stage uses; :meth:`Params.parse_text` does the same for command-line strings.
A problem is a :class:`ParamError` naming the key (callers add the file or flag); values that are
valid but a user should hear about (a descriptor radius that is no longer local) are
:meth:`Params.advisories`. Accepted types:
``bool`` (YAML booleans; on the command line true/false/yes/no/1/0), ``int`` (integers only, never
booleans), ``float`` (finite numbers; integers accepted), ``str`` and ``Literal[...]`` (one of the
listed values), each optionally ``| None`` (YAML ``null``; ``none`` on the command line), and
``tuple[float, ...]`` / ``tuple[int, ...]`` (a YAML list, comma-separated on the command line; the
bounds hold for every element).
``to_dict()`` is the canonical plain form (cache keys, result rows, ``harness methods``).
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from dataclasses import dataclass
from typing import Any, ClassVar, Literal, Mapping


def _no_such(key: str, specs) -> str:
    from harness.core.suggest import did_you_mean

    return f"no such parameter{did_you_mean(key, specs)}; known: {', '.join(specs) or 'none'}"


class ParamError(ValueError):
    """A bad parameter: ``key`` (None when the mapping itself is wrong) and the problem."""

    def __init__(self, key: str | None, problem: str):
        self.key, self.problem = key, problem
        super().__init__(f"{key}: {problem}" if key else problem)


def param(default, *, doc: str, ge=None, gt=None, le=None, lt=None, reading: str = "", choices=None,
          parse=None):
    """A parameter field: default, bounds (numbers), what it means (``doc``) and, for a reading of
    the paper, the sentence it reads (``reading``). Run-config sections (:mod:`harness.run.config.schema`)
    declare theirs the same way, with ``choices`` (a tuple, or a function returning the registered
    names) and, for a value that is no scalar (a list, a mapping), the function that reads it:
    ``parse(value, key, source) -> value``."""
    return dataclasses.field(default=default,
                             metadata={"doc": doc, "ge": ge, "gt": gt, "le": le, "lt": lt, "reading": reading,
                                       "choices": choices, "parse": parse})


@dataclass(frozen=True)
class ParamSpec:
    """One declared parameter, as tools show it."""

    name: str
    kind: str                      # "bool" | "int" | "float" | "str"
    optional: bool
    default: Any
    doc: str
    choices: tuple | None = None
    bounds: tuple = ()             # ((op, value), ...) with op in ">=", ">", "<=", "<"
    reading: str = ""
    many: bool = False             # a tuple of such values

    def describe(self) -> str:
        """``float > 0, <= 1`` / ``one of ucb, lcb`` / ``int or none`` / ``list of float >= -80`` ..."""
        if self.choices:
            text = "one of " + ", ".join(str(c) for c in self.choices)
        else:
            text = self.kind + "".join(f" {op} {v:g}" if i == 0 else f", {op} {v:g}"
                                       for i, (op, v) in enumerate(self.bounds))
        return ("list of " if self.many else "") + text + (" or none" if self.optional else "")


_OPS = {"ge": (">=", lambda v, b: v >= b), "gt": (">", lambda v, b: v > b),
        "le": ("<=", lambda v, b: v <= b), "lt": ("<", lambda v, b: v < b)}
_TRUE, _FALSE = {"true", "yes", "1", "on"}, {"false", "no", "0", "off"}


def _kind(hint) -> tuple[str, bool, tuple | None, bool]:
    """(kind, optional, choices, many) of a field's type hint."""
    optional = False
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        optional = len(args) < len(typing.get_args(hint))
        if len(args) != 1:
            raise TypeError(f"unsupported parameter type {hint!r}")
        hint, origin = args[0], typing.get_origin(args[0])
    if origin is Literal:
        choices = typing.get_args(hint)
        return type(choices[0]).__name__, optional, tuple(choices), False
    if hint in (bool, int, float, str):
        return hint.__name__, optional, None, False
    args = typing.get_args(hint)
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis and args[0] in (int, float):
        return args[0].__name__, optional, None, True
    raise TypeError(f"unsupported parameter type {hint!r}")


@dataclass(frozen=True)
class Params:
    """Base of every pruner's parameter class (see the module docstring)."""

    _specs: ClassVar[dict[type, tuple[ParamSpec, ...]]] = {}

    @classmethod
    def specs(cls) -> tuple[ParamSpec, ...]:
        if cls not in Params._specs:
            hints = typing.get_type_hints(cls)
            out = []
            for f in dataclasses.fields(cls):
                kind, optional, choices, many = _kind(hints[f.name])
                meta = f.metadata
                bounds = tuple((_OPS[k][0], meta[k]) for k in ("ge", "gt", "le", "lt") if meta.get(k) is not None)
                out.append(ParamSpec(f.name, kind, optional, f.default, meta.get("doc", ""), choices, bounds,
                                     meta.get("reading", ""), many))
            Params._specs[cls] = tuple(out)
        return Params._specs[cls]

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(s.name for s in cls.specs())

    @classmethod
    def parse(cls, values: Mapping[str, Any] | None = None):
        """The instance with ``values`` over the defaults, every value checked (:class:`ParamError`)."""
        values = {} if values is None else values
        if not isinstance(values, Mapping):
            raise ParamError(None, f"expected a mapping of parameter names to values, got {type(values).__name__}")
        specs = {s.name: s for s in cls.specs()}
        unknown = sorted(set(values) - set(specs), key=str)
        if unknown:
            raise ParamError(str(unknown[0]), _no_such(str(unknown[0]), specs))
        return cls(**{k: check_value(specs[k], v) for k, v in values.items()})

    @classmethod
    def parse_text(cls, values: Mapping[str, str]):
        """Like :meth:`parse`, from command-line strings (``--param k=v``, generated flags)."""
        specs = {s.name: s for s in cls.specs()}
        converted = {}
        for k, text in values.items():
            if k not in specs:
                raise ParamError(k, _no_such(k, specs))
            converted[k] = from_text(specs[k], text)
        return cls.parse(converted)

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def replace(self, **changes):
        return type(self).parse({**self.to_dict(), **changes})

    def advisories(self) -> list[str]:
        """Valid values whose combination a user should hear about (one sentence each); none by default.
        Commands print each once as a ``warning:`` line (:func:`harness.core.advice.warn_once`)."""
        return []


def check_value(spec: ParamSpec, value):
    """``value`` if it is a valid value of ``spec`` (ints widened to float for float fields; a list
    of a ``many`` field becomes a tuple, each element checked)."""
    if value is None:
        if spec.optional:
            return None
        raise ParamError(spec.name, "must not be null")
    if spec.many:
        if not isinstance(value, (list, tuple)):
            raise ParamError(spec.name, f"expected a list of {spec.kind} values, got {value!r}")
        one = dataclasses.replace(spec, many=False, optional=False)
        return tuple(check_value(one, v) for v in value)
    value = _typed(spec, value)
    if spec.choices is not None and value not in spec.choices:
        raise ParamError(spec.name, f"{value!r} is not one of {', '.join(map(str, spec.choices))}")
    for op, bound in spec.bounds:
        test = next(fn for o, fn in _OPS.values() if o == op)
        if not test(value, bound):
            raise ParamError(spec.name, f"{value!r} is not {op} {bound:g}")
    return value


def _typed(spec: ParamSpec, value):
    """``value`` if it is of ``spec``'s kind (an int widened to float for a float field)."""
    kind = spec.kind
    if kind == "bool":
        if not isinstance(value, bool):
            raise ParamError(spec.name, f"expected true or false, got {value!r}")
    elif kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ParamError(spec.name, f"expected an integer, got {value!r}")
    elif kind == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParamError(spec.name, f"expected a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise ParamError(spec.name, f"expected a finite number, got {value!r}")
    elif not isinstance(value, str):
        raise ParamError(spec.name, f"expected a string, got {value!r}")
    return value


def from_text(spec: ParamSpec, text: str):
    """The typed value of a command-line string for ``spec`` (checked by :func:`check_value`)."""
    t = text.strip()
    if spec.optional and t.lower() in ("none", "null"):
        return None
    if spec.many:
        one = dataclasses.replace(spec, many=False, optional=False)
        return [from_text(one, part) for part in t.split(",") if part.strip()]
    try:
        if spec.kind == "bool":
            if t.lower() in _TRUE:
                return True
            if t.lower() in _FALSE:
                return False
            raise ValueError
        if spec.kind == "int":
            return int(t)
        if spec.kind == "float":
            return float(t)
    except ValueError:
        raise ParamError(spec.name, f"expected {spec.describe()}, got {text!r}") from None
    return t
