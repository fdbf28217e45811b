"""What a table builder hands back: a :class:`Table` (or :class:`Missing`, saying why there is none).

A :class:`Table` carries the three views of one table:

* ``tidy``: long format, one header row, one row per observation (the ``.csv``);
* ``sections``: ``[(subtitle, DataFrame of display strings)]`` — one small table per group, each
  with a single header row (the ``.md``: readable in a terminal and on GitHub); empty = ``disp``;
* ``disp``: the wide paper layout (MultiIndex rows/columns of display strings: the ``.tex``).

``notes`` are printed under the table; ``warnings`` name what a partly built table lacks (a run
prints them in its summary); ``caption`` says what ``n`` is and how the intervals are computed (or
that there are none) — every output of the table shows it. Builders from before this module returned ``(num, disp,
notes)``; :func:`as_table` still accepts that, tidying ``num`` by :func:`tidy_from_wide`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd


@dataclass
class Table:
    disp: pd.DataFrame
    notes: list[str]
    tidy: pd.DataFrame
    sections: list[tuple[str, pd.DataFrame]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    caption: str = ""
    #: this table's own title, from what its rows hold (the registered title when empty)
    heading: str = ""


@dataclass(frozen=True)
class Missing:
    """A table that cannot be made from these results, and why (one line, naming what is missing)."""

    reason: str


def _level_names(index, default: str) -> list[str]:
    names = list(index.names)
    if len(names) == 1:
        return [names[0] or default]
    return [n or f"{default}_{i + 1}" for i, n in enumerate(names)]


def tidy_from_wide(num: pd.DataFrame, value: str = "value") -> pd.DataFrame:
    """One row per (row key, column key) of a wide numeric table: the index levels and the column
    levels become columns, the cell its ``value``."""
    rnames = _level_names(num.index, "row")
    cnames = _level_names(num.columns, "column")
    records = []
    for rkey, row in zip(num.index, num.itertuples(index=False)):
        rk = rkey if isinstance(rkey, tuple) else (rkey,)
        for ckey, v in zip(num.columns, row):
            ck = ckey if isinstance(ckey, tuple) else (ckey,)
            records.append((*rk, *ck, v))
    out = pd.DataFrame.from_records(records, columns=[*rnames, *cnames, value])
    if out[value].dtype == object:
        conv = pd.to_numeric(out[value], errors="coerce")
        if conv.notna().sum() == out[value].notna().sum():
            out[value] = conv.astype(np.float64)
    return out


def tidy_with_std(num: pd.DataFrame, std: pd.DataFrame) -> pd.DataFrame:
    """:func:`tidy_from_wide` of ``num`` with a ``std`` column: the same cell of ``std`` (a frame of
    ``num``'s shape holding each mean's standard deviation, NaN where a cell is not a mean)."""
    out = tidy_from_wide(num)
    out["std"] = pd.to_numeric(tidy_from_wide(std.reindex_like(num))["value"], errors="coerce").to_numpy()
    return out


def as_table(result) -> Table | Missing:
    """A builder's result as a :class:`Table` (None: :class:`Missing` without a specific reason)."""
    if isinstance(result, (Table, Missing)):
        return result
    if result is None:
        return Missing("no rows of these results fit this table")
    num, disp, notes = result
    return Table(disp=disp, notes=list(notes), tidy=tidy_from_wide(num))


@dataclass(frozen=True)
class Built:
    """One table as a run folder shows it: its file stem (``comparison``, ``comparison-shifted``),
    builder name, held-out view protocol ("" for results without one), title, and the table."""

    key: str
    name: str
    protocol: str
    title: str
    table: Table | Missing


@dataclass
class Written:
    """What writing a run's outputs produced: files, and one line per table or plot that could not
    be made (``missing``) or was made without some of its parts (``warnings``); ``built``: the
    tables as built (``{file stem: Built}``), for the report page; ``notes``: tables made for some
    held-out view protocols and not for others, whose results hold none of their variants (a method
    entry's ``protocols:``) — what the run measured, not a failure."""

    paths: list = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    built: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def __add__(self, other: "Written") -> "Written":
        return Written(self.paths + other.paths, self.missing + other.missing, self.warnings + other.warnings,
                       {**self.built, **other.built}, self.notes + other.notes)
