"""The ``findings`` table: what the claims table concludes, generated per protocol.

Built from the claims table's tidy rows alone (:func:`from_claims`: the ``claims*.csv`` a run writes),
so every number in it is one of that file's. Its caption counts the verdicts ("of 19 claims: 5 holds,
2 fails, …"); then one row per claim, grouped by verdict — holds, fails, depends on the reading,
inconclusive, underpowered, not comparable, not testable — with, under each reading, its verdict and
numbers: the pooled estimate over scenes with its interval where the claim pools, else the range of
the per-scene estimates with their marks.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from harness.report.tabledata import Missing, Table
from harness.study.claims import DEPENDS

ORDER = ("holds", "fails", DEPENDS, "inconclusive", "underpowered", "not comparable (render size)",
         "not testable here")
POOLED = "pooled over scenes"


def _numbers(rows: pd.DataFrame) -> str:
    """One reading's numbers of one claim (its tidy rows)."""
    if rows["scene"].eq("").all():
        return ""
    pooled = rows[rows["scene"] == POOLED]
    digits = 3 if rows["band_low"].abs().lt(1).all() and rows["mean"].abs().lt(1).all() else 2
    if len(pooled):
        return "; ".join(f"{r.comparison}: {r.mean:+.{digits}f} [{r.ci_low:+.{digits}f}, {r.ci_high:+.{digits}f}] "
                         f"over {int(r.n)} scenes" for r in pooled.itertuples())
    per = rows[rows["scene"] != POOLED]
    out = []
    for name, g in per.groupby("comparison", sort=False):
        marks = g["outcome"].value_counts()
        counts = ", ".join(f"{marks[o]} {m}" for o, m in (("holds", "✓"), ("fails", "✗"), ("unclear", "?"))
                           if marks.get(o))
        lo, hi = g["mean"].min(), g["mean"].max()
        span = f"{lo:+.{digits}f}" if np.isclose(lo, hi) else f"{lo:+.{digits}f} … {hi:+.{digits}f}"
        k = g["scene"].nunique()
        out.append(f"{name or 'Δ'}: {span} per scene ({k} scene{'s' * (k != 1)}; {counts})")
    return "; ".join(out)


def _reading_text(rows: pd.DataFrame) -> str:
    """"verdict (numbers)" of one claim under one reading, or why it has no numbers."""
    v = rows["verdict_reading"].iloc[0]
    if v == "not testable here":
        return f"{v}: {rows['why'].iloc[0]}"
    extra = ""
    if rows["verdict_direction"].iloc[0]:
        extra = f"direction {rows['verdict_direction'].iloc[0]}, size {rows['verdict_size'].iloc[0]}; "
    nums = _numbers(rows)
    return f"{v} ({extra}{nums})" if nums or extra else v


def from_claims(tidy: pd.DataFrame) -> pd.DataFrame:
    """One row per claim — verdict, key, claim (its line), the text under each reading — verdicts in
    :data:`ORDER`, claims in the table's order within a verdict."""
    tidy = tidy.copy()
    for c in ("scene", "why", "verdict_direction", "verdict_size", "comparison"):
        tidy[c] = tidy[c].fillna("").astype(str)
    readings = list(dict.fromkeys(tidy["reading"]))
    rows = []
    for key, claim in tidy.groupby("key", sort=False):
        first = claim.iloc[0]
        groups = dict(tuple(claim.groupby("reading", sort=False)))
        by = {r: _reading_text(g) for r, g in groups.items()}
        testable = [r for r, g in groups.items() if g["verdict_reading"].iloc[0] != "not testable here"]
        only = f" ({testable[0]} only)" if 0 < len(testable) < len(groups) else ""
        rows.append((first["verdict"] + only, key, f"{first['claim']} (L{str(first['lines']).split(',')[0]})",
                     *(by.get(r, "") for r in readings)))
    out = pd.DataFrame(rows, columns=["verdict", "key", "claim", *readings])
    rank = {v: i for i, v in enumerate(ORDER)}
    base = out["verdict"].str.replace(r" \(.* only\)$", "", regex=True)
    return out.iloc[np.argsort(base.map(lambda v: rank.get(v, len(ORDER))).to_numpy(), kind="stable")]


def table_findings(df: pd.DataFrame, overhead: dict | None = None):
    from harness.study.claims import table_claims

    claims = table_claims(df, overhead)
    if isinstance(claims, Missing):
        return claims
    found = from_claims(claims.tidy)
    counts = found["verdict"].str.replace(r" \(.* only\)$", "", regex=True).value_counts()
    summary = f"of {len(found)} claims: " + ", ".join(f"{counts[v]} {v}" for v in ORDER if v in counts)
    disp = found.set_index("key")
    notes = [summary,"generated from this protocol's claims table (claims*.csv): numbers are estimates of Δ with the "
             "interval that decided them; per-scene ranges with their marks (✓ holds, ✗ fails, ? unclear); rules: "
             "docs/claims.md", *claims.notes[:1]]
    return Table(disp, notes, found.reset_index(drop=True), caption=summary)
