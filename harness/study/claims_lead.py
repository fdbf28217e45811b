"""How the ``claims`` table leads the report page and colours its verdicts
(:mod:`harness.report.verdicts`: the product's hooks; this module fills them for the study).

* :func:`status_of` reads a cell's words as one status of the page's fixed vocabulary: a verdict
  cell of ``claims`` or ``findings`` starts with one of the study's verdicts (``holds``, ``fails``,
  ``inconclusive``, ``underpowered``, ``not testable here``, ``not comparable (render size)``,
  ``depends on the reading`` → ``mixed``); any other cell (a claim's words, its numbers) is no verdict.
* :func:`claim_items` turns a built ``claims`` table into the page's items, one per claim: its words
  and line; the paper's number, its type, where it is read and the claimed band (the detail line);
  the verdict over both readings, and each reading's verdict (a facet); as evidence, our numbers
  — pooled over scenes where the claim pools (its τ² and prediction interval left to the table),
  then one chunk per scene with its mark — read from the table's display sections, so the page
  prints the ``.md``'s numbers. Why a reading's verdict is not a plain one ("not testable here —
  the run has no …") is said once, in the evidence. The numbers shown are the main reading's
  (``paper-literal``, the default) and the other's only where its verdict differs: both for every
  claim would double every row, and where the readings agree the full table below has them.
"""

from __future__ import annotations

from harness.report.verdicts import FAILS, HOLDS, MIXED, NOT_COMPARABLE, NOT_TESTABLE, UNCLEAR, UNDERPOWERED, Item, Lead
from harness.study.claim_cells import READINGS
from harness.study.claims import DEPENDS

#: a verdict's first words -> the page's status (longest first: none is a prefix of another)
WORDS = {DEPENDS: MIXED, "not comparable": NOT_COMPARABLE, "not testable": NOT_TESTABLE,
         "underpowered": UNDERPOWERED, "inconclusive": UNCLEAR, "holds": HOLDS, "fails": FAILS}


def status_of(words: str) -> str | None:
    """The status a cell's words state (None: not a verdict)."""
    text = str(words).strip()
    return next((status for start, status in WORDS.items() if text.startswith(start)), None)


def _split(words: str) -> tuple[str, str]:
    """(the verdict, why) of ``"not testable here — the run has no …"``; an effect size's parts are
    dropped where they say the verdict again (``fails (direction: fails, size: fails)``: ``fails``)."""
    verdict, _, why = str(words).partition(" — ")
    head, _, parts = verdict.partition(" (")
    said = [p.partition(": ")[2] for p in parts.rstrip(")").split(", ")] if parts else []
    return (head if said and all(p == head for p in said) else verdict), why


def _evidence(reading: str, numbers, why: str) -> tuple[str, tuple[str, ...]]:
    """One reading's paragraph: its pooled estimates, then its per-scene chunks (or why it has none)."""
    pooled, per_scene = (str(x) for x in numbers)
    chunks = [c.split(" (k = ")[0] for c in pooled.split("; ") if c and c != "–"]  # τ², prediction: the table
    chunks += [c for c in per_scene.split(" · ") if c and c != "–"]
    if why:
        chunks.append(why)
    return reading, tuple(chunks)


def claim_items(table) -> list[Item]:
    """The page's items of a built ``claims`` table (module docstring), in the paper's order."""
    sections = dict(table.sections)
    verdicts = table.sections[0][1]
    numbers = {r: sections.get(f"the numbers under {r}") for r in READINGS}
    items = []
    for key, row in verdicts.iterrows():
        status = status_of(row["verdict"])
        said = {r: _split(row[r]) for r in READINGS}
        facets = tuple((r, status_of(words), words) for r, (words, _) in said.items())
        evidence = []
        for r, (words, why) in said.items():
            if r != READINGS[0] and status_of(words) == status_of(said[READINGS[0]][0]):
                continue  # the same verdict as the main reading's: its numbers are in the full table
            nums = numbers[r]
            has = nums is not None and key in nums.index
            evidence.append(_evidence(r, nums.loc[key].iloc[:2] if has else ("", ""), why))
        untestable = status == NOT_TESTABLE
        note = "; ".join(f"{r}: {why}" for r, (_, why) in said.items() if why) if untestable else ""
        items.append(Item(
            key=str(key), what=str(row["claim"]), status=status, verdict=str(row["verdict"]),
            detail=f"paper: {row['paper']} · {row['type']} · {row['at']} · claimed {row['claimed band']}",
            facets=facets, note=note,
            evidence=() if untestable else tuple(e for e in evidence if e[1])))
    return items


LEAD = Lead(items=claim_items, noun=("claim", "claims"),
            phrases={MIXED: ("depends on the reading", "depend on the reading")},
            evidence="our numbers under the main reading (and the other where its verdict differs): pooled over "
                     "scenes, then per scene (✓ holds, ✗ fails, ? unclear; ↑ ↓ above / below 0)")
