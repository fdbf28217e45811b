"""DataFrame (display strings, MultiIndex rows/columns) -> markdown and LaTeX in the paper's style.

LaTeX: one header line per column level with ``\\multicolumn`` spans over equal neighbours, the
first row level as ``\\multirow`` (needs ``\\usepackage{multirow}``), ``**x**`` markdown bold
becomes ``\\textbf{x}``; ↑/↓ become ``$\\uparrow$``/``$\\downarrow$``; Δ, ‡, ≥, · and τ become math.
Every other character LaTeX gives a meaning to (``\\ { } $ & # ^ _ % ~ < >``) is escaped in every
cell, label, title and note (:func:`tex_escape`), so a scene label such as ``\\input{/etc/passwd}``
is printed, never executed.

Markdown: one table per section of a :class:`~harness.report.tabledata.Table` (each with one header
row), or — for a plain display frame with two column levels — a header row of parent labels (once per
span) and a bold first row of the child labels.
"""

from __future__ import annotations

import re

import pandas as pd


def _levels(index) -> list[tuple]:
    return [t if isinstance(t, tuple) else (t,) for t in index]


def _names(index) -> list[str]:
    return [str(n) if n is not None else "" for n in index.names]


def md_escape(text) -> str:
    """A markdown table cell: one line, ``|`` escaped (a column break otherwise), ``<`` escaped
    (raw HTML otherwise); ``**bold**`` and the other inline marks of the cells are kept."""
    return " ".join(str(text).split()).replace("|", "\\|").replace("<", "\\<")


def _md_row(cells) -> str:
    return "| " + " | ".join(md_escape(c) for c in cells) + " |"


def _md_header(disp: pd.DataFrame, cols: list[tuple], n_idx: int) -> list[str]:
    """The header line and rule; column levels beyond the first as a bold first row."""
    depth = len(cols[0]) if cols else 1
    top = [c[0] if depth == 1 or i == 0 or cols[i - 1][0] != c[0] else "" for i, c in enumerate(cols)]
    lines = [_md_row(_names(disp.index) + top), "|" + "---|" * (n_idx + len(cols))]
    if depth > 1:
        lines.append(_md_row([""] * n_idx + [f"**{' · '.join(str(x) for x in c[1:] if str(x))}**" for c in cols]))
    return lines


def _md_table(disp: pd.DataFrame) -> list[str]:
    """One markdown table; column levels beyond the first give a second header line, written as a
    bold first row (GitHub has one header row), and a parent label is written once per span."""
    cols = _levels(disp.columns)
    lines = _md_header(disp, cols, len(_names(disp.index)))
    prev = None
    for r, vals in zip(_levels(disp.index), disp.itertuples(index=False)):
        shown = [("" if prev is not None and i < len(r) - 1 and r[: i + 1] == prev[: i + 1] else str(x))
                 for i, x in enumerate(r)]
        lines.append(_md_row(shown + [str(v) for v in vals]))
        prev = r
    return lines


def to_markdown(table, title: str, notes=()) -> str:
    """A :class:`~harness.report.tabledata.Table` (one table per section) or a display DataFrame."""
    caption = ""
    if hasattr(table, "sections"):
        notes, caption = table.notes, table.caption
        parts = [(s, d) for s, d in table.sections] or [("", table.disp)]
    else:
        parts = [("", table)]
    lines = [f"### {title}", ""] + ([f"_{caption}_", ""] if caption else [])
    for sub, disp in parts:
        if sub:
            lines += [f"#### {sub}", ""]
        lines += _md_table(disp) + [""]
    lines += [f"_{n}_" for n in notes]
    return "\n".join(lines).rstrip() + "\n"


#: LaTeX's special characters, each printed as itself
_TEX_SPECIAL = {"\\": r"\textbackslash{}", "{": r"\{", "}": r"\}", "$": r"\$", "&": r"\&", "#": r"\#",
                "^": r"\textasciicircum{}", "_": r"\_", "%": r"\%", "~": r"\textasciitilde{}",
                "<": r"\textless{}", ">": r"\textgreater{}"}
_TEX_RE = re.compile("|".join(re.escape(c) for c in _TEX_SPECIAL))


def tex_escape(text) -> str:
    """``text`` as LaTeX that prints it: every special character escaped in one pass (so an escape
    is never escaped again), line breaks made spaces."""
    return _TEX_RE.sub(lambda m: _TEX_SPECIAL[m.group()], " ".join(str(text).split()))


def _tex(text) -> str:
    t = tex_escape(text)
    t = re.sub(r"\*\*(.+?)\*\*", r"\\textbf{\1}", t)
    return (t.replace("↑", r"$\uparrow$").replace("↓", r"$\downarrow$").replace("Δ", r"$\Delta$")
            .replace("–", "--").replace("−", "$-$").replace("×", r"$\times$").replace("‡", r"$^\ddagger$")
            .replace("≥", r"$\geq$").replace("·", r"$\cdot$").replace("τ", r"$\tau$"))


def _spans(values: list) -> list[tuple[str, int]]:
    out: list[list] = []
    for v in values:
        if out and out[-1][0] == v:
            out[-1][1] += 1
        else:
            out.append([v, 1])
    return [(v, n) for v, n in out]


def _tex_header(disp: pd.DataFrame, cols: list[tuple], n_idx: int) -> list[str]:
    """One line per column level, a label spanning its columns; spans break where any higher level
    changes, so groups never straddle a parent boundary."""
    out, depth = [], len(cols[0]) if cols else 1
    for lvl in range(depth):
        lead = [_tex(n) for n in _names(disp.index)] if lvl == 0 else [""] * n_idx
        parts = [rf"\multicolumn{{{n}}}{{c|}}{{{_tex(key[-1])}}}" if n > 1 else _tex(key[-1])
                 for key, n in _spans([c[: lvl + 1] for c in cols])]
        out.append(" & ".join(lead + parts) + r" \\")
        out.append(rf"\cline{{{n_idx + 1}-{n_idx + len(cols)}}}" if lvl < depth - 1 else r"\hline")
    return out


def _tex_body(disp: pd.DataFrame, rows: list[tuple]) -> list[str]:
    """The rows, grouped by their first index level (one ``\\multirow`` label and a rule per group)."""
    out, i = [], 0
    for first, n in _spans([r[0] for r in rows]):
        for j in range(n):
            lead = [(rf"\multirow{{{n}}}{{*}}{{{_tex(first)}}}" if n > 1 else _tex(first)) if j == 0 else ""]
            lead += [_tex(x) for x in rows[i + j][1:]]
            out.append(" & ".join(lead + [_tex(v) for v in disp.iloc[i + j]]) + r" \\")
        out.append(r"\hline")
        i += n
    return out


def to_latex(disp: pd.DataFrame, title: str, notes=(), label: str = "") -> str:
    rows = _levels(disp.index)
    cols = _levels(disp.columns)
    n_idx = len(rows[0]) if rows else 1
    inner = [c[:-1] if len(c) > 1 else c for c in cols]  # one column block per method (paper style)
    spec = "|" + "c" * n_idx + "|" + "|".join("c" * n for _, n in _spans(inner)) + "|"
    out = [r"\begin{table}[t]", r"\centering", r"\resizebox{\linewidth}{!}{%", rf"\begin{{tabular}}{{{spec}}}",
           r"\hline", *_tex_header(disp, cols, n_idx), *_tex_body(disp, rows)]
    out += [r"\end{tabular}}", rf"\caption{{{_tex(title)}." + "".join(f" {_tex(n)}" for n in notes) + "}"]
    if label:
        out.append(rf"\label{{{re.sub(r'[^A-Za-z0-9:_.-]', '-', label)}}}")
    out.append(r"\end{table}")
    return "\n".join(out) + "\n"
