"""``<run>/report.html``: one self-contained page of a run (no network, no external file).

Sections: the run at a glance (what is missing from it); the tables with their confidence
intervals (:mod:`harness.report.cells`; a Δ whose 95 % CI excludes 0 is tinted green when it is
better than the reference in the metric's direction, red when worse); the rate–quality curves and
figures from ``<run>/plots/``; per scene × method × variant × ratio an image comparison of the first
held-out view — a slider between the reference render (left) and the pruned one (right), and the
amplified difference (:mod:`harness.report.pageimages`); and the run record (config, commit, machine,
stage times, cache counts, skips, errors). Images are ``data:`` URIs; the only script is the slider's.
"""

from __future__ import annotations

import html
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd

from harness.core import ratios
from harness.report import catalog
from harness.report.pageimages import AMPLIFY, JPEG_QUALITY, file_uri, scene_images
from harness.report.record import _slug
from harness.report.tabledata import Missing, Table

CSS = """
:root{--w:240px}
body{font:14px/1.45 system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0;color:#1d2327;background:#fafafa}
header{background:#22303c;color:#fff;padding:14px 24px}header h1{margin:0;font-size:20px}
header p{margin:4px 0 0;color:#c9d3dc}nav{padding:6px 24px;background:#e9eef2;position:sticky;top:0;z-index:5}
nav a{margin-right:16px;color:#22303c}main{padding:8px 24px 40px}h2{border-bottom:2px solid #ccd5dd;padding-top:12px}
table{border-collapse:collapse;margin:6px 0 14px;font-size:12.5px;background:#fff}
th,td{border:1px solid #d5dde3;padding:3px 7px;text-align:right;white-space:nowrap}
th{background:#eef2f5}td.k{text-align:left;font-weight:600}td small{color:#444}td.better{background:#dff3e1}td.worse{background:#f8dede}
.notes{color:#555;font-size:12px;margin:0 0 10px}.warn{background:#fff4d6;border:1px solid #e8c96b;padding:8px 12px}
.scroll{overflow-x:auto}.plots img{max-width:100%;border:1px solid #ddd;margin:4px 0;background:#fff}
details{background:#fff;border:1px solid #d5dde3;margin:8px 0;padding:4px 10px}summary{font-weight:600;cursor:pointer}
table.imgs td,table.imgs th{vertical-align:top;text-align:left;white-space:normal;background:#fff}table.imgs th{width:150px;max-width:150px;vertical-align:middle}table.imgs tr:first-child th{vertical-align:bottom}table.imgs td figure{vertical-align:top}.cmp{margin:0;width:var(--w)}
.slider{position:relative;width:var(--w);background-size:100% 100%;border:1px solid #999;overflow:hidden}
.slider img{position:absolute;inset:0;width:100%;height:100%;clip-path:inset(0 0 0 50%)}
.slider .bar{position:absolute;top:0;bottom:0;left:50%;width:2px;background:#ffcc00;pointer-events:none}
.slider input{position:absolute;left:0;right:0;bottom:4px;width:96%;margin:0 2%}
.tag{position:absolute;top:3px;font-size:11px;background:rgba(0,0,0,.55);color:#fff;padding:0 4px}
.tag.l{left:3px}.tag.r{right:3px}.diff{width:var(--w);display:block;image-rendering:pixelated;border:1px solid #999;margin-top:4px}
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
"""

_CI = re.compile(r"\[([+-]?[\d.]+), ([+-]?[\d.]+)\]")


def esc(x) -> str:
    return html.escape(str(x), quote=True)


def _tint(text: str, heading: str) -> str:
    """``better``/``worse`` when the cell's CI excludes 0 (direction from the heading's ↑/↓)."""
    m = _CI.search(text)
    if not m:
        return ""
    lo, hi = float(m.group(1)), float(m.group(2))
    if lo <= 0 <= hi:
        return ""
    up = lo > 0
    return "better" if up == ("↓" not in heading) else "worse"


def _cell(text: str) -> str:
    """A cell's text, its Δ and CI on a second, smaller line (narrow columns)."""
    if " (Δ " in text and text.endswith(")"):
        main, rest = text.split(" (", 1)
        return f"{esc(main)}<br><small>{esc(rest[:-1])}</small>"
    if " [" in text:
        main, ci = text.split(" [", 1)
        return f"{esc(main)}<br><small>[{esc(ci)}</small>"
    return esc(text)


def html_table(disp: pd.DataFrame, heading: str = "") -> str:
    names = [n or "" for n in disp.index.names]
    cols = [" · ".join(str(x) for x in c if str(x)) if isinstance(c, tuple) else str(c) for c in disp.columns]
    out = ["<div class='scroll'><table><thead><tr>"]
    out += [f"<th>{esc(h)}</th>" for h in names + cols]
    out.append("</tr></thead><tbody>")
    prev = None
    for key, vals in zip(disp.index, disp.itertuples(index=False)):
        key = key if isinstance(key, tuple) else (key,)
        out.append("<tr>")
        for i, k in enumerate(key):
            same = prev is not None and key[: i + 1] == prev[: i + 1] and i < len(key) - 1
            out.append(f"<td class='k'>{'' if same else esc(k)}</td>")
        for v in vals:
            cls = _tint(str(v), heading or str(key[0]))
            out.append(f"<td class='{cls}'>{_cell(str(v))}</td>" if cls else f"<td>{_cell(str(v))}</td>")
        out.append("</tr>")
        prev = key
    out.append("</tbody></table></div>")
    return "".join(out)


def tables_html(built: dict, titles: dict) -> str:
    out = []
    from harness.report.summary import PROTOCOL_NOTES

    for name, t in built.items():
        base, _, proto = name.partition("-") if name not in titles else (name, "", "")
        title = titles.get(base, name) + (f" — held-out views: {proto} ({PROTOCOL_NOTES.get(proto, '')})"
                                          if proto else "")
        out.append(f"<h3 id='t-{esc(name)}'>{esc(title)}</h3>")
        if isinstance(t, Missing):
            out.append(f"<p class='warn'>Not made from these results: {esc(t.reason)}</p>")
            continue
        for w in t.warnings:
            out.append(f"<p class='warn'>{esc(w)}</p>")
        for sub, disp in (t.sections or [("", t.disp)]):
            if sub:
                out.append(f"<h4>{esc(sub)}</h4>")
            out.append(html_table(disp, sub))
        out += [f"<p class='notes'>{esc(n)}</p>" for n in t.notes]
    return "\n".join(out)


def plots_html(plots_dir: Path) -> str:
    files = sorted(plots_dir.glob("curves_*.png")) + [plots_dir / f for f in ("figure1.png", "figure3.png")] \
        + sorted(plots_dir.glob("photos-*.png"))  # photo | unpruned | pruned (harness.report.photofigure)
    out = [f"<figure><img alt='{esc(f.stem)}' src='{file_uri(f)}'><figcaption>{esc(f.name)}</figcaption></figure>"
           for f in files if f.is_file()]
    return "<div class='plots'>" + ("\n".join(out) or "<p class='warn'>no plots in this run folder</p>") + "</div>"


def _fmt_db(v: float) -> str:
    return "inf (identical)" if np.isinf(v) else f"{v:.2f} dB"


def images_html(scenes) -> str:
    if not scenes:
        return "<p class='warn'>no stored renders under images/ (runs before the report page kept only a few)</p>"
    out = [f"<p class='notes'>First held-out view of each scene. Slider: reference render (left) | pruned render "
           f"(right), JPEG q{JPEG_QUALITY} viewing copies. Below: the largest |pruned − reference| of the R, G, B "
           f"channels × {AMPLIFY}, from the lossless renders (black = identical; a difference of "
           f"≥ {255 // AMPLIFY + 1} levels is white). "
           f"PSNR: this 8-bit pair.</p><p><label>image width <input id='imgw' type='range' min='160' max='720' "
           f"value='240'></label></p>"]
    for i, s in enumerate(scenes):
        ar = f"aspect-ratio:{s.width}/{s.height}"
        cls = f"ref-{_slug(s.scene)}".replace(".", "_")
        cols = sorted({c.ratio for c in s.comparisons})
        groups: dict = {}
        for c in s.comparisons:
            groups.setdefault((c.method, c.variant), {})[c.ratio] = c
        out.append(f"<style>.{cls}{{background-image:url('{s.reference}')}}</style>")
        out.append(f"<details{' open' if i == 0 else ''} id='img-{esc(_slug(s.scene))}'><summary>{esc(s.label)} — "
                   f"{len(s.comparisons)} pruned render(s)</summary><div class='scroll'><table class='imgs'><tr>"
                   f"<th><img class='refimg' alt='reference {esc(s.label)}' src='{s.reference}'><br>reference "
                   f"(unpruned), {s.width}×{s.height}</th>"
                   + "".join(f"<th>{ratios.percent(r)} pruned</th>" for r in cols) + "</tr>")
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


def _kv(rows) -> str:
    def show(v):
        return f"{v:.2f}" if isinstance(v, float) else v

    return "<table>" + "".join(f"<tr><th>{esc(k)}</th><td style='text-align:left'>{esc(show(v))}</td></tr>"
                               for k, v in rows) + "</table>"


def record_html(meta: dict) -> str:
    if not meta:
        return "<p class='warn'>no run.json in this folder</p>"
    m = meta.get("machine") or {}
    rows = [("name", meta.get("name", "")), ("when", meta.get("when", "")), ("commit", meta.get("commit", "")),
            ("config", meta.get("config_path", "")), ("command", " ".join(["harness", *meta.get("argv", [])])),
            ("workers", meta.get("workers", "")), ("CPU seconds", meta.get("cpu_seconds", "")),
            ("calibration (s)", meta.get("calibration_s", ""))] + [(f"machine: {k}", v) for k, v in m.items()]
    stages = meta.get("stage_seconds") or {}
    counts = meta.get("cache_counts") or {}
    out = ["<h3>Run</h3>", _kv(rows), "<h3>Stage seconds</h3>",
           _kv([(k, f"{v:.1f}" if isinstance(v, (int, float)) else v) for k, v in stages.items()]),
           "<h3>Cache (hits / misses)</h3>",
           _kv([(k, f"{c.get('hits', 0)} / {c.get('misses', 0)}") for k, c in counts.items()])]
    for key, title in (("skipped", "Skipped"), ("errors", "Errors")):
        items = meta.get(key) or []
        if items:
            out += [f"<h3>{title}</h3><pre>{esc(json.dumps(items, indent=1, default=str))}</pre>"]
    out += ["<h3>Config</h3>", f"<pre>{esc(json.dumps(meta.get('config', {}), indent=2, default=str))}</pre>"]
    return "\n".join(out)


def render_page(*, title: str, subtitle: str, warnings, tables: str, plots: str, images: str, record: str) -> str:
    warn = "".join(f"<p class='warn'>{esc(w)}</p>" for w in warnings)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width,initial-scale=1">
<title>{esc(title)}</title><link rel="icon" href="data:,"><style>{CSS}</style></head>
<body><header><h1>{esc(title)}</h1><p>{esc(subtitle)}</p></header>
<nav><a href="#tables">Tables</a><a href="#plots">Curves &amp; figures</a><a href="#images">Images</a>
<a href="#record">Run record</a></nav>
<main>{warn}
<h2 id="tables">Tables</h2>{tables}
<h2 id="plots">Curves &amp; figures</h2>{plots}
<h2 id="images">Image comparisons</h2>{images}
<h2 id="record">Run record</h2>{record}
</main><script>{JS}</script></body></html>
"""


def write_report(run_dir: str | Path, df: pd.DataFrame, meta: dict, built: dict | None = None,
                 missing=(), **opts) -> Path:
    """:func:`_write_report` with each method's budget note in its label (:func:`catalog.budget_notes`)."""
    with catalog.budget_notes(df):
        return _write_report(run_dir, df, meta, built, missing, **opts)


def _write_report(run_dir: str | Path, df: pd.DataFrame, meta: dict, built: dict | None = None,
                  missing=(), **opts) -> Path:
    """Write ``<run>/report.html`` from the results, the run record, ``plots/`` and ``images/``.
    ``built``: tables already built (``{name: Table | Missing}``), else built here from run.json's
    table list; ``missing``: lines about what else could not be made (plots)."""
    import tempfile

    from harness.io.files import atomic_write_text
    from harness.report.plots import plot_curves
    from harness.report.tables import BUILDERS, TITLES, build_tables

    run_dir = Path(run_dir)
    if built is None:
        names = [n for n in (meta.get("tables") or list(BUILDERS)) if n in BUILDERS]
        built = build_tables(df, names + ["versus"] * ("versus" not in names), **opts)
    warnings = [f"{n}: {t.reason}" for n, t in built.items() if isinstance(t, Missing)]
    warnings += [w for t in built.values() if isinstance(t, Table) for w in t.warnings]
    warnings += [m for m in missing if not m.startswith("table ")]  # tables: said above, from ``built``
    plots_dir = run_dir / "plots"
    with tempfile.TemporaryDirectory() as tmp:
        if not any(plots_dir.glob("curves_*.png")):  # a run folder without plots: draw the curves here
            plots_dir = Path(tmp)
            plot_curves(df, plots_dir)
        plots = plots_html(plots_dir)
    scenes = list(dict.fromkeys(zip(df["scene"], df["label"])))
    known = {_slug(m): m for m in df["method"].unique()}
    images = images_html(scene_images(run_dir / "images", scenes, known))
    ok = df[df["status"] == "ok"]
    subtitle = (f"{len(scenes)} scene(s), {ok['method'].nunique()} method(s), {len(ok)} measured image pairs; "
                f"commit {meta.get('commit', 'unknown')}; {meta.get('when', '')}")
    page = render_page(title=f"harness run {meta.get('name') or run_dir.name}", subtitle=subtitle,
                       warnings=warnings, tables=tables_html(built, TITLES), plots=plots, images=images,
                       record=record_html(meta))
    path = run_dir / "report.html"
    atomic_write_text(path, page)
    return path
