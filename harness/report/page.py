"""``<run>/report.html``: one self-contained page of a run (no network, no external file).

Built only by :func:`harness.report.outputs.publish` from the tables it has just written, so the
page shows the numbers of ``tables/`` — whichever of ``harness run``, ``harness tables`` or
``harness report`` wrote it. Order, summary first and the rest folded (``<details>``):

* **Bottom line** (when a table leads the page: :mod:`harness.report.verdicts`, e.g. the study's
  ``claims``): one paragraph from its verdicts under the main protocol — what holds, fails, is
  mixed, inconclusive, underpowered, not testable, counted and named — and how each other protocol's
  verdicts differ (:mod:`harness.report.pagelead`);
* **Summary**: the lead table of the main protocol, its cells coloured by verdict, then the
  protocol's headline table — the comparison's first metric (else the versus table's) — with its
  caption; every other protocol's lead and headline folded under a line with its counts. Without a
  lead table: per protocol the headline table;
* **Tables**: every table of every protocol, each folded, titled with its protocol; each HTML table
  has a caption with ``n`` and the interval method (:mod:`harness.report.cells`) and scrolls inside
  its box when wider than the page;
* **Curves & figures** from ``<run>/plots/``;
* **Images**: an index of every scene, then per scene × method × variant × ratio an image comparison
  of the first held-out view — a slider between the reference render (left) and the pruned one
  (right), and the amplified difference (:mod:`harness.report.pageimages`); a link opens its scene;
* **Run records**: every run into the folder (``records/``: a cold run and its cached rerun both
  listed), each in full when unfolded.

Images are ``data:`` URIs; the only script is the slider's and the one opening a linked section.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from harness.core import jsonout, ratios
from harness.report import catalog, pagelead
from harness.report.pagehtml import esc, html_table, kv_table
from harness.report.pageimages import AMPLIFY, JPEG_QUALITY, file_uri, scene_images
from harness.report.pagestyle import CSS, JS
from harness.report.record import read_records, slug
from harness.report.tabledata import Built, Missing, Table


# --------------------------------------------------------------------------- tables
def _verdicts(name: str):
    """The registered ``verdicts`` of table ``name`` (None: its cells are tinted by their intervals)."""
    from harness.report.tables import TABLE_SPECS

    return TABLE_SPECS.get(name).verdicts if name in TABLE_SPECS else None


def table_html(b: Built, sections=None, cls: str = "", elsewhere: bool = False) -> str:
    """One table: warnings, its sections (each an HTML table with the caption), notes. A missing
    table made for another protocol (``elsewhere``) is a note: this protocol measured none of its
    variants (a method entry's ``protocols:``). A table of verdicts wraps its cells and colours
    them by the verdict they state."""
    t = b.table
    if isinstance(t, Missing):
        if elsewhere:
            return f"<p class='notes'>Not measured under the {esc(b.protocol)} views: {esc(t.reason)}</p>"
        return f"<p class='warn'>Not made from these results: {esc(t.reason)}</p>"
    verdicts = _verdicts(b.name)
    cls = cls or ("wrap" if verdicts else "")
    out = [f"<p class='warn'>{esc(w)}</p>" for w in t.warnings]
    for sub, disp in sections if sections is not None else (t.sections or [("", t.disp)]):
        if sub:
            out.append(f"<h4>{esc(sub)}</h4>")
        out.append(html_table(disp, sub, t.caption, cls, verdicts))
    out += [f"<p class='notes'>{esc(n)}</p>" for n in t.notes]
    return "\n".join(out)


def headline_html(built: dict[str, Built], proto: str) -> str:
    """A protocol's headline table: the comparison's first section, else the versus table's ("" if neither)."""
    head = next((b for name in ("comparison", "versus") for b in built.values()
                 if b.name == name and b.protocol == proto and isinstance(b.table, Table)), None)
    if head is None:
        return ""
    first = (head.table.sections or [("", head.table.disp)])[:1]
    return "\n".join([f"<h3>{esc(head.title)}</h3>", table_html(head, first),
                      f"<p class='notes'><a href='#t-{esc(head.key)}'>every metric of this table</a></p>"])


def _leads(built: dict[str, Built]) -> tuple[dict[str, tuple[Built, object, list]], str]:
    """({protocol: (its lead table, the table's Lead, its items)} for the first table registered as a
    lead that was made for some protocol, a problem): a lead whose items are not valid (a status
    outside the vocabulary) leads nothing, and the problem says why."""
    from harness.report.tables import TABLE_SPECS

    made = [b for b in built.values() if isinstance(b.table, Table) and b.name in TABLE_SPECS
            and TABLE_SPECS.get(b.name).lead is not None]
    if not made:
        return {}, ""
    lead = TABLE_SPECS.get(made[0].name).lead
    try:
        return {b.protocol: (b, lead, list(lead.items(b.table))) for b in made if b.name == made[0].name}, ""
    except ValueError as err:
        return {}, f"the {made[0].name} table cannot lead this page: {err}"


def summary_html(built: dict[str, Built]) -> tuple[str, str]:
    """(bottom line, summary). With a lead table (:mod:`harness.report.pagelead`): the bottom line of
    the main protocol, its lead table and headline, then every other protocol's folded; without
    one, no bottom line and per protocol the headline table."""
    from harness.views.protocols import notes

    protocols = list(dict.fromkeys(b.protocol for b in built.values()))
    leads, problem = _leads(built)
    if not leads:
        out = "\n".join(h for h in (headline_html(built, p) for p in protocols) if h)
        if problem:
            return "", f"<p class='warn'>{esc(problem)}</p>" + out
        return "", out or "<p class='warn'>no table could be made from these results</p>"
    main = next(iter(leads))
    b, lead, items = leads[main]
    others = {p: leads[p][2] if p in leads else None for p in protocols if p != main}
    bottom = pagelead.bottom_line(main, items, lead, others, notes)
    out = [f"<h3 id='s-{esc(b.key)}'>{esc(b.title)}</h3>", pagelead.lead_table(items, lead, main, b.table.caption),
           headline_html(built, main)]
    if others:
        out.append("<h3>The other held-out view protocols</h3>")
    for p in others:
        counted = pagelead.counts(leads[p][2], lead) if p in leads else "no verdicts"
        body = (pagelead.lead_table(leads[p][2], lead, p, leads[p][0].table.caption) if p in leads else "")
        out.append(f"<details id='s-{esc(slug(p))}'><summary>{esc(p)} views <small>({esc(notes(p))}): {counted}"
                   f"</small></summary>{body}{headline_html(built, p)}</details>")
    return bottom, "\n".join(out)


def made_elsewhere(built: dict[str, Built]) -> set[str]:
    """Names of the tables made for at least one protocol (a missing one of these is a note)."""
    return {b.name for b in built.values() if isinstance(b.table, Table)}


def tables_html(built: dict[str, Built]) -> str:
    """Every table, folded, grouped by held-out view protocol (each summary names it too)."""
    from harness.report.tables import base_title
    from harness.views.protocols import notes

    out = []
    for proto in dict.fromkeys(b.protocol for b in built.values()):
        if proto:
            out.append(
                f"<h3>Held-out views: {esc(proto)} <small>({esc(notes(proto))})"
                "</small></h3>"
            )
        made = made_elsewhere(built)
        for b in (b for b in built.values() if b.protocol == proto):
            elsewhere = isinstance(b.table, Missing) and b.name in made
            tag = "" if not isinstance(b.table, Missing) else (
                " <small>(not measured under this protocol)</small>" if elsewhere
                else " <small>(not made from these results)</small>")
            name = base_title(b.name) + (f" — {proto} views" if proto else "")
            body = table_html(b, elsewhere=elsewhere)
            out.append(f"<details id='t-{esc(b.key)}'><summary>{esc(name)}{tag}</summary>{body}</details>")
    return "\n".join(out)


# --------------------------------------------------------------------------- plots, images
def plots_html(files, protocol: str = "") -> str:
    """The plots just drawn (:func:`harness.report.plots.write_plots`), each folded, in their order."""
    out = [f"<details><summary>{esc(f.name)}</summary><figure><img alt='{esc(f.stem)}' src='{file_uri(f)}'>"
           f"</figure></details>" for f in map(Path, files) if f.is_file()]
    if not out:
        return "<p class='warn'>no plots in this run folder</p>"
    note = f"<p class='notes'>Held-out views: {esc(protocol)} (the primary protocol).</p>" if protocol else ""
    return note + "<div class='plots'>" + "\n".join(out) + "</div>"


def _fmt_db(v: float) -> str:
    return "inf (identical)" if np.isinf(v) else f"{v:.2f} dB"


def _scene_html(s, cls: str) -> str:
    ar = f"aspect-ratio:{s.width}/{s.height}"
    cols = sorted({c.ratio for c in s.comparisons})
    groups: dict = {}
    for c in s.comparisons:
        groups.setdefault((c.method, c.variant), {})[c.ratio] = c
    out = [f"<style>.{cls}{{background-image:url('{s.reference}')}}</style>",
           f"<details id='img-{esc(slug(s.scene))}'><summary>{esc(s.label)} <small>{len(s.comparisons)} pruned "
           f"render(s)</small></summary><div class='scroll'><table class='imgs'><tr>"
           f"<th><img class='refimg' alt='reference {esc(s.label)}' src='{s.reference}'><br>reference "
           f"(unpruned), {s.width}×{s.height}</th>" + "".join(f"<th>{ratios.percent(r)} pruned</th>" for r in cols)
           + "</tr>"]
    for (method, variant), by_r in groups.items():
        name = catalog.method_label(method) + ("" if variant == "default" else f" [{variant}]")
        out.append(f"<tr><th>{esc(name)}</th>")
        for r in cols:
            c = by_r.get(r)
            if c is None:
                out.append("<td></td>")
                continue
            what = f"{name}, {ratios.percent(c.ratio)} pruned"
            out.append(
                f"<td><figure class='cmp'><div class='slider {cls}' style='{ar}'>"
                f"<img alt='{esc(what)}' src='{c.pruned}'><div class='bar'></div>"
                f"<span class='tag l'>reference</span><span class='tag r'>pruned</span>"
                f"<input type='range' min='0' max='100' value='50' aria-label='{esc('slider ' + what)}'></div>"
                f"<img class='diff' alt='{esc('difference ' + what)}' src='{c.diff}'>"
                f"<figcaption>PSNR {_fmt_db(c.psnr)} · max |Δ| {c.max_diff}/255</figcaption></figure></td>")
        out.append("</tr>")
    out.append("</table></div></details>")
    return "\n".join(out)


def images_html(scenes, protocol: str = "") -> str:
    if not scenes:
        return "<p class='warn'>no stored renders under images/</p>"
    index = " ".join(f"<a href='#img-{esc(slug(s.scene))}'>{esc(s.label)}</a>" for s in scenes)
    out = [
        f"<p class='index'>Scenes: {index}</p>",
        f"<p class='notes'>First held-out view{f' ({esc(protocol)})' if protocol else ''} of each scene. "
        "Slider: reference render (left) | pruned render "
        f"(right), JPEG q{JPEG_QUALITY} viewing copies. Below: the largest |pruned − reference| of the R, G, B "
        f"channels × {AMPLIFY}, from the lossless renders (black = identical; a difference of "
        f"≥ {255 // AMPLIFY + 1} levels is white). "
        f"PSNR: this 8-bit pair.</p><p><label>image width <input id='imgw' type='range' min='160' max='720' "
        f"value='240'></label></p>",
    ]
    out += [_scene_html(s, f"ref-{i}") for i, s in enumerate(scenes)]  # a CSS class: any scene name, one class
    return "\n".join(out)


# --------------------------------------------------------------------------- run records
def _hits(meta: dict) -> str:
    counts = meta.get("cache_counts") or {}
    return f"{sum(c.get('hits', 0) for c in counts.values())} / {sum(c.get('misses', 0) for c in counts.values())}"


def _seconds(v) -> str:
    return f"{v:.1f}" if isinstance(v, (int, float)) and not isinstance(v, bool) else "–"


def _record_detail(meta: dict) -> str:
    m = meta.get("machine") or {}
    rows = [("name", meta.get("name", "")), ("when", meta.get("when", "")), ("commit", meta.get("commit", "")),
            ("config", meta.get("config_path", "")), ("command", " ".join(["harness", *meta.get("argv", [])])),
            ("workers", meta.get("workers", "")), ("CPU seconds", meta.get("cpu_seconds", "")),
            ("calibration (s)", meta.get("calibration_s", ""))] + [(f"machine: {k}", v) for k, v in m.items()]
    stages = meta.get("stage_seconds") or {}
    counts = meta.get("cache_counts") or {}
    out = [kv_table(rows), "<h4>Stage seconds</h4>",
           kv_table([(k, f"{v:.1f}" if isinstance(v, (int, float)) else v) for k, v in stages.items()]),
           "<h4>Cache (hits / misses)</h4>",
           kv_table([(k, f"{c.get('hits', 0)} / {c.get('misses', 0)}") for k, c in counts.items()])]
    for key, title in (("skipped", "Skipped"), ("errors", "Errors")):
        if meta.get(key):
            out += [f"<h4>{title}</h4><pre>{esc(jsonout.dumps(meta[key], indent=1))}</pre>"]
    out += ["<h4>Config</h4>", f"<pre>{esc(jsonout.dumps(meta.get('config', {}), indent=2))}</pre>"]
    return "\n".join(out)


def records_html(records: list[dict], unreadable: list[str]) -> str:
    """A table of every run into the folder (newest first), then each record folded, the newest open."""
    if not records:
        return "<p class='warn'>no run record (run.json, records/) in this folder</p>"
    newest = list(reversed(records))
    rows = pd.DataFrame(
        [[r.get("commit", "")[:12], " ".join(["harness", *r.get("argv", [])]),
          _seconds((r.get("stage_seconds") or {}).get("total")), _hits(r),
          " / ".join(str((r.get("rows") or {}).get(k, "?")) for k in ("ok", "skipped", "error")),
          len(r.get("errors") or [])] for r in newest],
        pd.Index([r.get("when", "") for r in newest], name="when"),
        ["commit", "command", "total s", "cache hits / misses", "rows ok / skipped / error", "errors"])
    out = [html_table(rows, caption=f"{len(records)} run(s) into this folder, newest first; a cached rerun "
                                    "times only what it recomputed", cls="records")]
    out += [f"<p class='warn'>{esc(u)}</p>" for u in unreadable]
    out += [f"<details><summary>{esc(r.get('when', ''))} <small>{esc(' '.join(['harness', *r.get('argv', [])]))}"
            f"</small></summary>{_record_detail(r)}</details>" for r in newest]
    return "\n".join(out)


# --------------------------------------------------------------------------- the page
def render_page(*, title: str, subtitle: str, warnings, summary: str, tables: str, plots: str, images: str,
                records: str, notes=(), bottom: str = "") -> str:
    warn = ""
    if warnings:
        items = "".join(f"<li>{esc(w)}</li>" for w in warnings)
        warn = (f"<details class='warn'><summary>{len(warnings)} warning(s)</summary>"
                f"<ul class='warn'>{items}</ul></details>")
    if notes:
        items = "".join(f"<li>{esc(n)}</li>" for n in notes)
        warn += (f"<details class='note'><summary>{len(notes)} note(s): tables measured under some "
                 f"protocols only</summary><ul>{items}</ul></details>")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width,initial-scale=1">
<title>{esc(title)}</title><link rel="icon" href="data:,"><style>{CSS}</style></head>
<body><header><h1>{esc(title)}</h1><p>{esc(subtitle)}</p></header>
<nav><a href="#summary">Summary</a><a href="#tables">Tables</a><a href="#plots">Curves &amp; figures</a>
<a href="#images">Images</a><a href="#record">Run records</a></nav>
<main>{bottom}{warn}
<h2 id="summary">Summary</h2>{summary}
<h2 id="tables">Tables</h2>{tables}
<h2 id="plots">Curves &amp; figures</h2>{plots}
<h2 id="images">Image comparisons</h2>{images}
<h2 id="record">Run records</h2>{records}
</main><script>{JS}</script></body></html>
"""


def write_report(run_dir: str | Path, df: pd.DataFrame, meta: dict, built: dict[str, Built], missing=(),
                 plots=()) -> Path:
    """Write ``<run>/report.html`` from the tables just built (``{file stem: Built}``), the plots just
    drawn (``plots``: their files), the results, the run records and ``images/``; ``missing``: lines
    about what else could not be made (plots). Called by :func:`harness.report.outputs.publish` only."""
    from harness.io.files import atomic_write_text

    run_dir = Path(run_dir)
    warnings, notes = _problems(built, missing)
    scenes = list(dict.fromkeys(zip(df["scene"], df["label"])))
    known = {slug(n): n for col in ("method", "variant") if col in df for n in df[col].dropna().unique()}
    protocols = list(dict.fromkeys(b.protocol for b in built.values() if b.protocol))  # the primary first
    images = images_html(scene_images(run_dir / "images", scenes, known), protocols[0] if protocols else "")
    records, unreadable = read_records(run_dir)
    ok = df[df["status"] == "ok"]
    subtitle = (f"{len(scenes)} scene(s), {ok['method'].nunique()} method(s), {len(ok)} measured image pairs"
                + (f" under {len(protocols)} held-out view protocol(s) ({', '.join(protocols)})" if protocols else "")
                + f"; commit {meta.get('commit', 'unknown')}; {meta.get('when', '')}")
    bottom, summary = summary_html(built)
    page = render_page(title=f"harness run {meta.get('name') or run_dir.name}", subtitle=subtitle,
                       warnings=warnings, bottom=bottom, summary=summary, tables=tables_html(built),
                       plots=plots_html(plots, protocols[0] if protocols else ""), images=images,
                       records=records_html(records, unreadable), notes=notes)
    path = run_dir / "report.html"
    atomic_write_text(path, page)
    return path


def _problems(built: dict[str, Built], missing) -> tuple[list[str], list[str]]:
    """(warnings, notes) of the page: a table no protocol could make, a table's own warnings and a plot
    not drawn are warnings; a table made for other protocols than this one is a note."""
    made = made_elsewhere(built)
    absent = [b for b in built.values() if isinstance(b.table, Missing)]
    warnings = [f"{b.key}: {b.table.reason}" for b in absent if b.name not in made]
    notes = [f"{b.key}: not measured under the {b.protocol} views ({b.table.reason})" for b in absent if b.name in made]
    warnings += [w for b in built.values() if isinstance(b.table, Table) for w in b.table.warnings]
    warnings += [m for m in missing if not m.startswith("table ")]  # tables: said above, from ``built``
    return warnings, notes
