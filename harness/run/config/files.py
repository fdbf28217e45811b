"""Config files: ``extends:`` and where every value came from.

``extends: default.yaml`` (a path relative to the extending file) makes a config the named one with
this file's keys over it: mappings merge key by key, anything else — a list (``scenes``,
``methods``, ``tables``), a number, a string — replaces the base's value whole. A base may extend
another; a cycle is an error. The resolved document has no ``extends`` key.

:func:`read_config_file` also returns the **origin** of every value: ``{key path: "file:line"}``,
with key paths as tuples (``("protocol", "longest_side")``, ``("methods", 2, "params", "voxel")``),
so ``harness config show`` can say which file and line each setting comes from.
"""

from __future__ import annotations

from pathlib import Path

from harness.core.errors import InputError

#: at most this many files in one chain of ``extends``
MAX_DEPTH = 8


def _lines(node, path: tuple, out: dict, where: str) -> None:
    """``{key path: "file:line"}`` of every value under a composed YAML node."""
    import yaml

    out[path] = f"{where}:{node.start_mark.line + 1}"
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            _lines(v, path + (k.value,), out, where)
    elif isinstance(node, yaml.SequenceNode):
        for i, v in enumerate(node.value):
            _lines(v, path + (i,), out, where)


def _merge(base, over, base_origins: dict, over_origins: dict, path: tuple = ()):
    """``over`` on top of ``base`` (module docstring), with the origins of the merged values."""
    if isinstance(base, dict) and isinstance(over, dict):
        out = dict(base)
        for k, v in over.items():
            out[k] = _merge(base[k], v, base_origins, over_origins, path + (k,)) if k in base else v
            if k not in base or not (isinstance(base[k], dict) and isinstance(v, dict)):
                _take(base_origins, over_origins, path + (k,))
        return out
    _take(base_origins, over_origins, path)
    return over


def _take(base_origins: dict, over_origins: dict, path: tuple) -> None:
    """The origins under ``path`` become those of the overriding file."""
    for p in [p for p in base_origins if p[: len(path)] == path]:
        del base_origins[p]
    base_origins.update({p: o for p, o in over_origins.items() if p[: len(path)] == path})


def _extended(base_name, source: str, chain: tuple) -> Path:
    """The file ``extends: base_name`` names (relative to the extending file), checked: a path, no
    cycle, at most :data:`MAX_DEPTH` files, a file that exists."""
    if not isinstance(base_name, str) or not base_name.strip():
        raise InputError(source, f"extends: expected the path of a config file, got {base_name!r}")
    base_path = (Path(source).parent / base_name) if not Path(base_name).is_absolute() else Path(base_name)
    key = str(base_path.resolve())
    if key in chain or len(chain) >= MAX_DEPTH:
        raise InputError(source, f"extends: {base_name} extends this file again (a cycle)" if key in chain
                         else f"extends: more than {MAX_DEPTH} files in the chain")
    if not base_path.is_file():
        raise InputError(source, f"extends: no such config file {base_path}")
    return base_path


def resolve(doc, source: str, origins: dict | None = None, chain: tuple = ()) -> tuple:
    """``(document, origins)`` of a parsed config with its ``extends`` chain resolved."""
    from harness.io.safe_yaml import load_yaml

    origins = {} if origins is None else origins
    if not isinstance(doc, dict) or "extends" not in doc:
        return doc, origins
    base_path = _extended(doc["extends"], source, chain)
    key = str(base_path.resolve())
    base, node = load_yaml(base_path, with_node=True)
    base_origins: dict = {}
    if node is not None:
        _lines(node, (), base_origins, str(base_path))
    if not isinstance(base, dict):
        raise InputError(base_path, "top level: expected a mapping (the config this one extends)")
    base, base_origins = resolve(base, str(base_path), base_origins, chain + (key,))
    own = {k: v for k, v in doc.items() if k != "extends"}
    merged = _merge(base, own, base_origins, {p: o for p, o in origins.items() if p[:1] != ("extends",)})
    return merged, base_origins


def read_config_file(path: Path) -> tuple:
    """``(document, origins)`` of a config file, ``extends`` resolved (module docstring)."""
    from harness.io.safe_yaml import load_yaml

    doc, node = load_yaml(path, with_node=True)
    origins: dict = {}
    if node is not None:
        _lines(node, (), origins, str(path))
    return resolve(doc, str(path), origins, (str(Path(path).resolve()),))
