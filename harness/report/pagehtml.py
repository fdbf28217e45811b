"""HTML pieces of the report page: escaped text, tables of display strings, key–value lists.

A table cell is a display string of :mod:`harness.report.cells` (``62.85 (Δ +26.43 [+25.87, +27.00])``):
its mean on the first line, Δ and CI on a second, smaller one; a cell whose CI excludes 0 is tinted
green when it is better than the reference in the metric's direction (↑/↓ of its heading), red when
worse — except in a table of verdicts (``verdicts``: a cell's words -> its status,
:mod:`harness.report.verdicts`), where a cell is coloured by the verdict it states and never by a
sign. Markdown bold (``**63.87**``, the ablation's best of a row) becomes ``<strong>``: the page shows
no markdown syntax. Every table sits in a box that scrolls sideways, so no table is wider than the page,
and carries its ``caption`` (n and the interval method) as an HTML ``<caption>``.
"""

from __future__ import annotations

import html
import re

import pandas as pd

_CI = re.compile(r"\[([+-]?[\d.]+), ([+-]?[\d.]+)\]")
_BOLD = re.compile(r"\*\*(.+?)\*\*")


def esc(x) -> str:
    return html.escape(str(x), quote=True)


def text_html(text: str) -> str:
    """Escaped text with markdown bold as ``<strong>``."""
    return _BOLD.sub(lambda m: f"<strong>{m.group(1)}</strong>", esc(text))


def tint(text: str, heading: str) -> str:
    """``better``/``worse`` when the cell's CI excludes 0 (direction from the heading's ↑/↓)."""
    m = _CI.search(text)
    if not m:
        return ""
    lo, hi = float(m.group(1)), float(m.group(2))
    if lo <= 0 <= hi:
        return ""
    up = lo > 0
    return "better" if up == ("↓" not in heading) else "worse"


def status_class(status: str) -> str:
    """``v v-<status>`` (spaces as dashes): the CSS class of a cell stating that verdict."""
    return "v v-" + status.replace(" ", "-")


def colour(text: str, heading: str, verdicts=None) -> str:
    """A cell's class: its verdict's (``verdicts`` given: none for a cell that states no verdict),
    else :func:`tint`."""
    if verdicts is None:
        return tint(text, heading)
    status = verdicts(text)
    return status_class(status) if status else ""


def cell_html(text: str) -> str:
    """A cell's text, its Δ and CI on a second, smaller line (narrow columns)."""
    if " (Δ " in text and text.endswith(")"):
        main, rest = text.split(" (", 1)
        return f"{text_html(main)}<br><small>{esc(rest[:-1])}</small>"
    if " [" in text:
        main, ci = text.split(" [", 1)
        return f"{text_html(main)}<br><small>[{esc(ci)}</small>"
    return text_html(text)


def html_table(disp: pd.DataFrame, heading: str = "", caption: str = "", cls: str = "", verdicts=None) -> str:
    """A display frame as one scrolling HTML table (repeated row keys blanked, as in the .md);
    ``cls``: the table's class (``wrap``: cells wrap, for tables of sentences); ``verdicts``: see
    :func:`colour`."""
    names = [n or "" for n in disp.index.names]
    cols = [" · ".join(str(x) for x in c if str(x)) if isinstance(c, tuple) else str(c) for c in disp.columns]
    attr = f" class='{cls}'" if cls else ""
    out = [f"<div class='scroll'><table{attr}>"]
    if caption:
        out.append(f"<caption>{esc(caption)}</caption>")
    out.append("<thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in names + cols) + "</tr></thead><tbody>")
    prev = None
    for key, vals in zip(disp.index, disp.itertuples(index=False)):
        key = key if isinstance(key, tuple) else (key,)
        out.append(_row_html(key, vals, prev, heading, verdicts))
        prev = key
    out.append("</tbody></table></div>")
    return "".join(out)


def _row_html(key: tuple, vals, prev: tuple | None, heading: str, verdicts=None) -> str:
    """One row: its key cells (blank where they repeat the previous row's, but the last) and its values."""
    out = ["<tr>"]
    for i, k in enumerate(key):
        same = prev is not None and key[: i + 1] == prev[: i + 1] and i < len(key) - 1
        out.append(f"<td class='k'>{'' if same else esc(k)}</td>")
    for v in vals:
        cls = colour(str(v), heading or str(key[0]), verdicts)
        out.append(f"<td class='{cls}'>{cell_html(str(v))}</td>" if cls else f"<td>{cell_html(str(v))}</td>")
    out.append("</tr>")
    return "".join(out)


def kv_table(rows) -> str:
    """Two columns: key, value (floats with two decimals)."""
    def show(v):
        return f"{v:.2f}" if isinstance(v, float) else v

    return "<div class='scroll'><table class='kv'>" + "".join(
        f"<tr><th>{esc(k)}</th><td>{esc(show(v))}</td></tr>" for k, v in rows) + "</table></div>"
