"""YAML configs read safely: a checked regular file (:func:`harness.io.safe.read_text`: size-capped,
UTF-8), duplicate keys refused, and alias expansion bounded before any value is built — a "billion
laughs" document of a few hundred bytes is refused, not expanded. Every problem is one
:class:`~harness.core.errors.InputError` naming the file and line."""

from __future__ import annotations

from pathlib import Path

from harness.core.errors import InputError
from harness.io.safe import read_text

#: a YAML document may expand (aliases followed) to at most this many nodes: a "billion laughs"
#: document of a few hundred bytes is refused instead of being expanded when a value is used
MAX_YAML_NODES = 100_000
MAX_YAML_ALIASES = 1_000


def _yaml_loader():
    import yaml

    class Loader(yaml.SafeLoader):
        """SafeLoader that refuses duplicate keys and bounds alias expansion."""

        aliases = 0

        def compose_node(self, parent, index):
            if self.check_event(yaml.events.AliasEvent):
                self.aliases += 1
                if self.aliases > MAX_YAML_ALIASES:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"more than {MAX_YAML_ALIASES} aliases", self.peek_event().start_mark)
            return super().compose_node(parent, index)

        def construct_mapping(self, node, deep=False):
            seen = {}
            for key_node, _ in node.value:
                if isinstance(key_node, yaml.ScalarNode):
                    key = key_node.value
                    if key in seen:
                        raise yaml.constructor.ConstructorError(
                            None, None, f"duplicate key {key!r} (first at line {seen[key] + 1})", key_node.start_mark)
                    seen[key] = key_node.start_mark.line
            return super().construct_mapping(node, deep=deep)

    return Loader


def _expanded_nodes(node, memo: dict) -> int:
    """Node count of a composed YAML graph with every alias expanded (shared nodes memoised)."""
    import yaml

    key = id(node)
    if key in memo:
        return memo[key]
    memo[key] = MAX_YAML_NODES + 1  # a cycle counts as too big
    if isinstance(node, yaml.SequenceNode):
        n = 1 + sum(_expanded_nodes(v, memo) for v in node.value)
    elif isinstance(node, yaml.MappingNode):
        n = 1 + sum(_expanded_nodes(k, memo) + _expanded_nodes(v, memo) for k, v in node.value)
    else:
        n = 1
    memo[key] = min(n, MAX_YAML_NODES + 1)
    return memo[key]


def load_yaml(path: str | Path, what: str = "config", *, with_node: bool = False):
    """A YAML document from a checked regular file (size-capped, UTF-8), with duplicate keys and
    alias bombs refused; any problem is one InputError naming the file and line. ``with_node``:
    ``(document, its composed node)`` (the node's marks give each value's line)."""
    import yaml

    path = Path(path)
    text = read_text(path, "config", what)
    try:
        loader = _yaml_loader()(text)  # the reader refuses control characters and NUL here
    except yaml.YAMLError as err:
        raise InputError(path, f"invalid YAML: {_yaml_problem(err)}") from None
    try:
        node = loader.get_single_node()
        if node is None:
            return (None, None) if with_node else None
        if _expanded_nodes(node, {}) > MAX_YAML_NODES:
            raise InputError(path, f"YAML expands to more than {MAX_YAML_NODES:,} values (aliases); refusing it")
        doc = loader.construct_document(node)
        return (doc, node) if with_node else doc
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise InputError(path, f"invalid YAML{at}: {_yaml_problem(err)}") from None
    except RecursionError:
        raise InputError(path, "YAML nested too deeply") from None
    finally:
        loader.dispose()


def _yaml_problem(err) -> str:
    """One line of a YAML error: its ``problem`` text, else a control character the reader refused."""
    import yaml

    if isinstance(err, yaml.reader.ReaderError):
        return (
            f"character {err.character!r} "
            f"(code {ord(err.character) if isinstance(err.character, str) else err.character})"
            f" at byte {err.position} is not allowed in YAML (control character or NUL)"
        )
    return str(getattr(err, "problem", None) or err)
