"""The top of the report page when a table leads it (:mod:`harness.report.verdicts`): the bottom
line, the lead table of the main held-out view protocol, and the other protocols folded.

* **Bottom line**: one paragraph from the verdicts of the main protocol (the first whose lead table
  was made: the training rig's views when it was) — how many items hold, fail, are mixed,
  inconclusive, underpowered, not comparable or not testable, each group named (linked to its row)
  — ending with one sentence on how each other protocol's verdicts differ over the items both judge.
* **Lead table**: one row per judged item — what (with its source), the verdict (a narrow column,
  coloured by its status), one narrow column per facet (e.g. per reading, coloured by its own
  status), and the evidence in the one wide column, each chunk (one scene's estimate) kept on one
  line and ✓ / ✗ in the holds / fails colours. The items not testable under that protocol are not
  rows: one folded note line names them (unfolded: why each is not).
* Then the protocol's headline table (the comparison), handed in by the page; the other protocols'
  lead tables and headlines follow, each folded under a line with its counts.

Colours are the status's (``v-holds`` …), never the sign of a Δ.
"""

from __future__ import annotations

from collections.abc import Callable

from harness.report.pagehtml import esc, status_class
from harness.report.record import slug
from harness.report.verdicts import NOT_TESTABLE, Difference, Item, Lead, by_status, compare


def anchor(protocol: str, key: str) -> str:
    return f"lead-{slug(protocol)}-{slug(key)}"


def _words(words: str) -> str:
    """A verdict's words, a parenthesis or a dash clause on a second, smaller line."""
    for sep, keep in ((" (", "("), (" — ", "")):
        if sep in words:
            main, rest = words.split(sep, 1)
            return f"{esc(main)}<br><small>{esc(keep + rest)}</small>"
    return esc(words)


#: a chunk longer than this may wrap inside (a pooled estimate with its τ² and prediction interval)
LONG_CHUNK = 56


def _chunk(text: str) -> str:
    """One chunk of evidence: unbroken (one scene's estimate) unless longer than :data:`LONG_CHUNK`."""
    marked = esc(text).replace("✓", "<b class='m-holds'>✓</b>").replace("✗", "<b class='m-fails'>✗</b>")
    return f"<span class='{'cw' if len(text) > LONG_CHUNK else 'c'}'>{marked}</span>"


def _evidence(item: Item) -> str:
    out = [f"<p class='why'>{esc(item.note)}</p>"] if item.note else []
    for label, chunks in item.evidence:
        head = f"<b>{esc(label)}:</b> " if label else ""
        out.append(f"<p>{head}{' · '.join(map(_chunk, chunks)) or '–'}</p>")
    return "".join(out) or "–"


def _row(item: Item, facets: list[str], protocol: str) -> str:
    own = {name: (status, words) for name, status, words in item.facets}
    ident = anchor(protocol, item.key)
    cells = [f"<td class='what'><a id='{ident}' href='#{ident}'>{esc(item.key)}</a> {esc(item.what)}"
             + (f"<br><small>{esc(item.detail)}</small>" if item.detail else "") + "</td>",
             f"<td class='{status_class(item.status)}'>{_words(item.verdict)}</td>"]
    for name in facets:
        status, words = own.get(name, ("", ""))
        cells.append(f"<td class='{status_class(status)}'>{_words(words)}</td>" if status else "<td></td>")
    cells.append(f"<td class='ev'>{_evidence(item)}</td>")
    return "<tr>" + "".join(cells) + "</tr>"


def lead_table(items: list[Item], lead: Lead, protocol: str, caption: str = "") -> str:
    """The judged items as one table (the not-testable ones as one folded note line below it)."""
    shown = [i for i in items if i.status != NOT_TESTABLE]
    facets = list(dict.fromkeys(name for i in shown for name, _, _ in i.facets))
    out = []
    if shown:
        head = "".join(f"<th class='v'>{esc(h)}</th>" for h in ("verdict", *facets))
        cap = f"<caption>{esc(caption)}</caption>" if caption else ""
        out.append("<div class='scroll'><table class='lead'>" + cap
                   + f"<thead><tr><th class='what'>{esc(lead.noun[0])}</th>{head}<th class='ev'>{esc(lead.evidence)}"
                   "</th></tr></thead><tbody>" + "".join(_row(i, facets, protocol) for i in shown)
                   + "</tbody></table></div>")
    untestable = [i for i in items if i.status == NOT_TESTABLE]
    if untestable:
        names = ", ".join(esc(i.key) for i in untestable)
        reasons = "".join(f"<li id='{anchor(protocol, i.key)}'><b>{esc(i.key)}</b> {esc(i.what)}: "
                          f"{esc(i.note or i.verdict)}</li>" for i in untestable)
        out.append(f"<details class='untestable'><summary>{lead.count(len(untestable))} "
                   f"{lead.phrase(NOT_TESTABLE, len(untestable))}: {names}</summary><ul>{reasons}</ul></details>")
    return "\n".join(out)


def counts(items: list[Item], lead: Lead, protocol: str | None = None) -> str:
    """``2 hold (a, b); 4 fail (…); …``, each count in its status's colour; item names linked to
    their rows of ``protocol``'s lead table (not linked when None)."""
    parts = []
    for status, group in by_status(items).items():
        names = ", ".join(f"<a href='#{anchor(protocol, i.key)}'>{esc(i.key)}</a>" if protocol is not None
                          else esc(i.key) for i in group)
        parts.append(f"<span class='{status_class(status)}'>{len(group)} {esc(lead.phrase(status, len(group)))}"
                     f"</span> ({names})")
    return "; ".join(parts)


def _difference(d: Difference, lead: Lead) -> str:
    if d.missing:
        return f"{esc(d.protocol)} has no verdicts (the table was not made there)"
    n = d.same + len(d.changed)
    if n == 0:
        text = f"{esc(d.protocol)} judges none of them"
    elif not d.changed:
        text = f"{esc(d.protocol)} agrees on all {n}"
    else:
        changed = ", ".join(f"<a href='#{anchor(d.protocol, k)}'>{esc(k)}</a> {esc(lead.phrase(s, 1))}"
                            for k, s in d.changed)
        text = f"{esc(d.protocol)} agrees on {d.same} of {n} and differs on {len(d.changed)} ({changed})"
    return text + (f" ({d.untestable} more not testable there)" if d.untestable else "")


def bottom_line(protocol: str, items: list[Item], lead: Lead, others: dict[str, list[Item] | None],
                describe: Callable[[str], str] = lambda p: "") -> str:
    """The page's first paragraph (module docstring); ``others``: each other protocol's items (None
    where its lead table was not made); ``describe(protocol)``: a few words on the protocol."""
    about = describe(protocol)
    where = "" if not protocol else (f", under the {esc(protocol)} views"
                                     + (f" ({esc(about)}; the main protocol)" if about else ""))
    text = f"<b>Bottom line</b>{where}: of {lead.count(len(items))}, {counts(items, lead, protocol)}."
    diffs = [_difference(compare(p, items, got), lead) for p, got in others.items()]
    if diffs:
        text += f" The other protocols, over the {lead.noun[1]} both judge: " + "; ".join(diffs) + "."
    return f"<p class='bottom' id='bottom-line'>{text}</p>"
