"""``harness config show CONFIG``: the resolved config, every value with where it came from.

Each line is ``key: value  # origin``, the origin a ``file:line`` (the config, or a file it
``extends``) or ``default`` (the declared default of the field, :mod:`harness.run.config.sections`,
or a pruner's own parameter default). Method entries are shown as the variants they expand to, with
the parameters the config sets (the others are the pruner's defaults: ``harness methods``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from harness.run.config.executor import ExecutorSpec
from harness.run.config.files import read_config_file
from harness.run.config.run_config import SECTIONS, RunConfig, parse_config
from harness.run.config.schema import declared
from harness.run.config.sections import Protocol, SceneSpec, Settings

WIDTH = 60


def _text(v) -> str:
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return format(v, "g")
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_text(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}: {_text(x)}" for k, x in v.items()) + "}"
    if dataclasses.is_dataclass(v):
        return "{" + ", ".join(f"{f.name}: {_text(getattr(v, f.name))}" for f in dataclasses.fields(v)) + "}"
    return str(v)


class _Lines:
    def __init__(self, origins: dict):
        self.origins, self.out = origins, []

    def origin(self, *paths: tuple) -> str:
        """The origin of the first of ``paths`` a file gave (``default`` when none did)."""
        return next((self.origins[p] for p in paths if p in self.origins), "default")

    def add(self, indent: int, key: str, value, *paths: tuple) -> None:
        text = f"{' ' * indent}{key}: {_text(value)}"
        self.out.append(f"{text:<{WIDTH}}  # {self.origin(*paths)}" if paths else text)


def _section(lines: _Lines, obj, cls, indent: int, base: tuple, fallback: tuple | None = None) -> None:
    """Every declared field of section ``obj``; an absent one from ``fallback`` + its name, if given
    there (a scene's ``n_test`` from ``protocol.n_test``)."""
    for f in declared(cls):
        paths = [base + (f.name,)] + ([fallback + (f.name,)] if fallback else [])
        lines.add(indent, f.name, getattr(obj, f.name), *paths)


def show(path: str | Path) -> str:
    """The resolved config of the file at ``path`` (module docstring)."""
    doc, origins = read_config_file(Path(path))
    config: RunConfig = parse_config(doc, str(path))
    lines = _Lines(origins)
    chain = sorted({o.rsplit(":", 1)[0] for o in origins.values()} - {str(path)})
    lines.out.append(f"# {path}" + (f" (extends {', '.join(chain)})" if chain else ""))
    top = {"name": config.name, "output": config.output, "workers": config.workers, "anchor": config.anchor,
           "ratios": (doc or {}).get("ratios", ()), "keep": (doc or {}).get("keep", ()), "tables": config.tables,
           "plots": config.plots}
    for f in declared(Settings):
        lines.add(0, f.name, top[f.name], (f.name,))
    lines.out.append("executor:")
    _section(lines, config.executor, ExecutorSpec, 2, ("executor",))
    lines.out.append("protocol:")
    _section(lines, config.protocol, Protocol, 2, ("protocol",))
    lines.add(0, "protocols", [p.name for p in config.protocols], ("protocols",))
    lines.out.append("scenes:")
    for i, s in enumerate(config.scenes):
        lines.add(2, "- name", s.name, ("scenes", i, "name"), ("scenes", i))
        lines.add(4, "label", s.label, ("scenes", i, "label"))
        _section(lines, s, SceneSpec, 4, ("scenes", i), fallback=("protocol",))
    lines.out.append("methods:")
    _methods(lines, doc, config)
    return "\n".join(lines.out)


def _methods(lines: _Lines, doc: dict, config: RunConfig) -> None:
    """Each entry's variants: ratios, scenes, protocols, and the parameters the entry sets or sweeps."""
    entries = [({"name": e} if isinstance(e, str) else e) for e in doc.get("methods", [])]
    variants = iter(config.methods)
    for i, e in enumerate(entries):
        given = {**(e.get("params") or {}), **dict.fromkeys(e.get("sweep") or {})}
        combos = 1
        for vals in (e.get("sweep") or {}).values():
            combos *= len(vals)
        for _ in range(combos):
            v = next(variants)
            at = ("methods", i)
            lines.add(2, f"- {v.key}", v.method, at + ("name",), at)
            lines.add(4, "ratios", v.ratios, at + ("ratios",), at + ("keep",), ("ratios",), ("keep",))
            lines.add(4, "scenes", v.scenes or "all", at + ("scenes",))
            lines.add(4, "protocols", v.protocols or "all", at + ("protocols",))
            params = v.params.to_dict()
            for k in given:
                lines.add(4, f"params.{k}", params[k], at + ("params", k), at + ("sweep", k))
            rest = len(params) - len(given)
            if rest:
                lines.out.append(
                    f"    # {rest} other parameter(s) at the pruner's defaults (harness methods {v.method})"
                )


__all__ = ["SECTIONS", "show"]
