"""``<run>/report.html``: one self-contained page of a run (no network, no external file).

Built only by :func:`harness.report.outputs.publish` from the tables it has just written, so the
page shows the numbers of ``tables/`` — whichever of ``harness run``, ``harness tables`` or
``harness report`` wrote it. Order, summary first and the rest folded (``<details>``):

* **Summary**: the ``claims`` table when the run has one, then per held-out view protocol the
  headline table — the comparison's first metric (else the versus table's) — with its caption;
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
from harness.report import catalog
from harness.report.pagehtml import esc, html_table, kv_table
from harness.report.pageimages import AMPLIFY, JPEG_QUALITY, file_uri, scene_images
from harness.report.record import read_records, slug
from harness.report.tabledata import Built, Missing, Table

CSS = """
:root{--w:240px}
body{font:14px/1.45 system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0;color:#1d2327;background:#fafafa}
header{background:#22303c;color:#fff;padding:14px 24px}header h1{margin:0;font-size:20px}
header p{margin:4px 0 0;color:#c9d3dc}nav{padding:6px 24px;background:#e9eef2;position:sticky;top:0;z-index:5}
nav a{margin-right:16px;color:#22303c}main{padding:8px 24px 40px;max-width:100%;box-sizing:border-box}
h2{border-bottom:2px solid #ccd5dd;padding-top:12px}h3{margin:14px 0 4px}h3 small{font-weight:400;color:#555}
table{border-collapse:collapse;margin:6px 0 14px;font-size:12.5px;background:#fff}
caption{caption-side:top;text-align:left;font-size:12px;color:#444;padding:2px 0 4px;white-space:normal}
th,td{border:1px solid #d5dde3;padding:3px 7px;text-align:right;white-space:nowrap}
th{background:#eef2f5;white-space:normal;min-width:3em;max-width:16em}td.k{text-align:left;font-weight:600}
td small{color:#444}td.better{background:#dff3e1}td.worse{background:#f8dede}
table.kv td{text-align:left;white-space:normal}
table.wrap td{text-align:left;white-space:normal;min-width:5em}
details.note{background:#eef4fb;border:1px solid #b9cde5;padding:8px 12px}
.notes{color:#555;font-size:12px;margin:0 0 10px}.warn{background:#fff4d6;border:1px solid #e8c96b;padding:8px 12px}
ul.warn{margin:8px 0;padding-left:28px}
.scroll{overflow-x:auto;max-width:100%}.plots img{max-width:100%;border:1px solid #ddd;margin:4px 0;background:#fff}
details{background:#fff;border:1px solid #d5dde3;margin:8px 0;padding:4px 10px;min-width:0}
summary{font-weight:600;cursor:pointer}summary small{font-weight:400;color:#555}
details,h2,h3{scroll-margin-top:44px}table.records td{white-space:normal;text-align:left}
.index a{margin-right:14px}
table.imgs td,table.imgs th{vertical-align:top;text-align:left;white-space:normal;background:#fff}
table.imgs th{width:150px;max-width:150px;vertical-align:middle}table.imgs tr:first-child th{vertical-align:bottom}
table.imgs td figure{vertical-align:top}.cmp{margin:0;width:var(--w)}
.slider{position:relative;width:var(--w);background-size:100% 100%;border:1px solid #999;overflow:hidden}
.slider img{position:absolute;inset:0;width:100%;height:100%;clip-path:inset(0 0 0 50%)}
.slider .bar{position:absolute;top:0;bottom:0;left:50%;width:2px;background:#ffcc00;pointer-events:none}
.slider input{position:absolute;left:0;right:0;bottom:4px;width:96%;margin:0 2%}
.tag{position:absolute;top:3px;font-size:11px;background:rgba(0,0,0,.55);color:#fff;padding:0 4px}
.tag.l{left:3px}.tag.r{right:3px}
.diff{width:var(--w);display:block;image-rendering:pixelated;border:1px solid #999;margin-top:4px}
figcaption{font-size:12px;color:#333}.refimg{width:150px;border:1px solid #999}
pre{background:#fff;border:1px solid #ddd;padding:8px;overflow-x:auto;font-size:12px;max-height:420px}
"""

JS = """
var w = document.getElementById('imgw');
if (w) w.addEventListener('input', function () {
  document.documentElement.style.setProperty('--w', w.value + 'px');
});
document.querySelectorAll('.slider input').forEach(function (s) {
  function set() {
    var box = s.parentNode, v = s.value + '%';
    box.querySelector('img').style.clipPath = 'inset(0 0 0 ' + v + ')';
    box.querySelector('.bar').style.left = v;
  }
  s.addEventListener('input', set);
  set();
});
function openTarget() {
  var t = location.hash && document.getElementById(decodeURIComponent(location.hash.slice(1)));
  for (var e = t; e; e = e.parentElement) if (e.tagName === 'DETAILS') e.open = true;
  if (t) t.scrollIntoView();
}
window.addEventListener('hashchange', openTarget);
openTarget();
"""


# --------------------------------------------------------------------------- tables
def table_html(b: Built, sections=None, cls: str = "", elsewhere: bool = False) -> str:
    """One table: warnings, its sections (each an HTML table with the caption), notes. A missing
    table made for another protocol (``elsewhere``) is a note: this protocol measured none of its
    variants (a method entry's ``protocols:``)."""
    t = b.table
    if isinstance(t, Missing):
        if elsewhere:
            return f"<p class='notes'>Not measured under the {esc(b.protocol)} views: {esc(t.reason)}</p>"
        return f"<p class='warn'>Not made from these results: {esc(t.reason)}</p>"
    out = [f"<p class='warn'>{esc(w)}</p>" for w in t.warnings]
    for sub, disp in sections if sections is not None else (t.sections or [("", t.disp)]):
        if sub:
            out.append(f"<h4>{esc(sub)}</h4>")
        out.append(html_table(disp, sub, t.caption, cls))
    out += [f"<p class='notes'>{esc(n)}</p>" for n in t.notes]
    return "\n".join(out)


def summary_html(built: dict[str, Built]) -> str:
    """The claims table(s), then per protocol the headline table's first section."""
    out = []
    for b in built.values():
        if b.name == "claims":  # its cells are sentences: wrapped, so the verdict column is in view
            out += [f"<h3 id='s-{esc(b.key)}'>{esc(b.title)}</h3>", table_html(b, cls="wrap")]
    protocols = list(dict.fromkeys(b.protocol for b in built.values()))
    for proto in protocols:
        head = next((b for name in ("comparison", "versus") for b in built.values()
                     if b.name == name and b.protocol == proto and isinstance(b.table, Table)), None)
        if head is None:
            continue
        first = (head.table.sections or [("", head.table.disp)])[:1]
        out += [f"<h3>{esc(head.title)}</h3>", table_html(head, first),
                f"<p class='notes'><a href='#t-{esc(head.key)}'>every metric of this table</a></p>"]
    return "\n".join(out) or "<p class='warn'>no table could be made from these results</p>"


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
            body = table_html(b, cls="wrap" if b.name == "claims" else "", elsewhere=elsewhere)
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
                records: str, notes=()) -> str:
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
<main>{warn}
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
    page = render_page(title=f"harness run {meta.get('name') or run_dir.name}", subtitle=subtitle,
                       warnings=warnings, summary=summary_html(built), tables=tables_html(built),
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
