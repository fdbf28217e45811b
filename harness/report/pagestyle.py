"""The report page's style sheet and its one script (:mod:`harness.report.page`).

Verdict colours (``v-<status>``, :mod:`harness.report.verdicts`) are fixed, one per status, so a
colour means the same on every page: holds green, fails red, mixed (depends on the reading) violet,
inconclusive amber, underpowered blue-grey, not comparable and not testable grey. They colour a
verdict only, never a sign; the ``better``/``worse`` tints of the other tables are paler.
"""

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
.bottom{font-size:15px;line-height:1.55;background:#fff;border:1px solid #ccd5dd;border-left:6px solid #22303c;
padding:10px 14px;margin:12px 0}.bottom a{color:inherit}
table.lead td.v{font-weight:600}table.lead td.v small{font-weight:400}
.v-holds{background:#cdebd3;color:#0d4a1f}.v-fails{background:#f5c9c9;color:#74100f}
.v-mixed{background:#e4d8f5;color:#3f1f6e}.v-inconclusive{background:#fbeec4;color:#5c4500}
.v-underpowered{background:#dfe6ee;color:#28384a}
.v-not-comparable,.v-not-testable{background:#ececec;color:#444}
span.v{padding:0 4px;border-radius:3px;font-weight:600}b.m-holds{color:#137a2e}b.m-fails{color:#b3191b}
table.lead{width:100%;table-layout:fixed}
table.lead td,table.lead th{text-align:left;white-space:normal;vertical-align:top}
table.lead th.what{width:23%}table.lead th.v{width:8.5em;font-weight:600}table.lead th.ev{width:auto}
table.lead td.what a{font-weight:600;color:#22303c}table.lead td.ev p{margin:0 0 2px}table.lead td{line-height:1.38}
table.lead .c{white-space:nowrap}table.lead .why{font-style:italic;color:#444}
details.untestable{background:#f6f6f6;font-size:12.5px}details.untestable summary{font-weight:400}
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
