"""Verdicts a table can give, and the bottom line the report page opens with.

A table that judges things (the paper study's ``claims``: each claim holds, fails, …) registers
two hooks with :func:`harness.report.tables.register_table`:

* ``verdicts=status_of``: ``status_of(words) -> status | None`` reads a cell's words as one status of
  the fixed vocabulary :data:`STATUSES` (None: the cell is not a verdict). The page then colours
  that table's verdict cells by their status and never tints a cell by the sign of an interval: a
  claim that fails is red even where its Δ is positive.
* ``lead=Lead(items=...)``: the table leads the page. ``items(table)`` turns the built table
  (its tidy rows, the ``.csv``, and its display sections) into :class:`Item` s — what is judged, its
  status, the verdict in the table's words, per facet (e.g. per reading) a status of its own, the
  evidence — and the page opens with :func:`bottom_line` of the main (first) held-out view protocol,
  then these items as a table, the other protocols' folded (:mod:`harness.report.pagelead`).

The vocabulary is fixed so that colours and sentences mean the same on every page:

=================  ==========================================================================
``holds``          the data support the claim as stated
``fails``          the data contradict it
``mixed``          its parts disagree (the study's "depends on the reading")
``inconclusive``   neither: the intervals straddle the bound
``underpowered``   too few scenes for a verdict (the numbers are still shown)
``not comparable`` measured, but not comparably with the claim (another render size)
``not testable``   the run cannot test it (a cell it needs was not measured)
=================  ==========================================================================
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

HOLDS, FAILS, MIXED, UNCLEAR = "holds", "fails", "mixed", "inconclusive"
UNDERPOWERED, NOT_COMPARABLE, NOT_TESTABLE = "underpowered", "not comparable", "not testable"
#: every status, in the order the bottom line names them
STATUSES = (HOLDS, FAILS, MIXED, UNCLEAR, UNDERPOWERED, NOT_COMPARABLE, NOT_TESTABLE)
#: the bottom line's words for each status: (one item, several)
PHRASES = {HOLDS: ("holds", "hold"), FAILS: ("fails", "fail"), MIXED: ("is mixed", "are mixed"),
           UNCLEAR: ("is inconclusive", "are inconclusive"), UNDERPOWERED: ("is underpowered", "are underpowered"),
           NOT_COMPARABLE: ("is not comparable", "are not comparable"),
           NOT_TESTABLE: ("is not testable here", "are not testable here")}


@dataclass(frozen=True)
class Item:
    """One judged thing of a lead table (a claim).

    ``key`` names it (linkable); ``what`` says what is judged (one line) and ``detail`` where it
    comes from (a smaller line: the paper's number, the claimed band); ``status`` is its verdict in
    :data:`STATUSES`, ``verdict`` the same in the table's words; ``facets`` one (name, status,
    words) per facet it is also judged under (the readings); ``note`` why a verdict is not a plain
    one (not testable, not comparable); ``evidence`` the numbers, as (label, chunks) paragraphs —
    a chunk (one scene's estimate) never breaks across lines, the page wraps between chunks."""

    key: str
    what: str
    status: str
    verdict: str
    detail: str = ""
    facets: tuple[tuple[str, str, str], ...] = ()
    note: str = ""
    evidence: tuple[tuple[str, tuple[str, ...]], ...] = ()

    def __post_init__(self):
        bad = [s for s in (self.status, *(f[1] for f in self.facets)) if s not in STATUSES]
        if bad:
            raise ValueError(f"item {self.key!r}: status {bad[0]!r} is not one of {', '.join(STATUSES)}")


@dataclass(frozen=True)
class Lead:
    """How a table leads the page: ``items(table) -> list[Item]`` (``table`` a
    :class:`harness.report.tabledata.Table`), ``noun`` what one item is called (one, several),
    ``phrases`` the bottom line's words for a status where the table has its own (``{MIXED:
    ("depends on the reading", "depend on the reading")}``), ``facets`` the title of the facet
    columns (``"reading"``) and ``evidence`` the title of the evidence column."""

    items: Callable
    noun: tuple[str, str] = ("item", "items")
    phrases: Mapping[str, tuple[str, str]] = field(default_factory=dict)
    evidence: str = "evidence"

    def phrase(self, status: str, n: int) -> str:
        one, several = self.phrases.get(status, PHRASES[status])
        return one if n == 1 else several

    def count(self, n: int) -> str:
        return f"{n} {self.noun[0] if n == 1 else self.noun[1]}"


@dataclass(frozen=True)
class Difference:
    """How one other protocol's verdicts compare with the main protocol's, over the items both
    judged (``same``: as many with the same status; ``changed``: (key, its status there));
    ``untestable``: items judged under the main protocol but not testable there; ``missing``: the
    lead table was not made there at all."""

    protocol: str
    same: int = 0
    changed: tuple[tuple[str, str], ...] = ()
    untestable: int = 0
    missing: bool = False


def by_status(items: list[Item]) -> dict[str, list[Item]]:
    """The items grouped by status, in :data:`STATUSES` order (statuses without items left out)."""
    groups = {s: [i for i in items if i.status == s] for s in STATUSES}
    return {s: g for s, g in groups.items() if g}


def compare(protocol: str, main: list[Item], other: list[Item] | None) -> Difference:
    """``other`` (a protocol's items; None: its lead table was not made) against ``main``."""
    if other is None:
        return Difference(protocol, missing=True)
    there = {i.key: i.status for i in other}
    judged = [i for i in main if i.status != NOT_TESTABLE and i.key in there]
    untestable = sum(there[i.key] == NOT_TESTABLE for i in judged)
    both = [i for i in judged if there[i.key] != NOT_TESTABLE]
    changed = tuple((i.key, there[i.key]) for i in both if there[i.key] != i.status)
    return Difference(protocol, len(both) - len(changed), changed, untestable)
