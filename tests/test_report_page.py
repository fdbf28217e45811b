"""report.html: self-contained, faithful difference images, tables with CIs, run record; and in a real
headless Chromium: no console errors, every image decodes, the slider moves, the screenshot is not blank."""

from __future__ import annotations

import base64
import io
import json
import math
import re

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from harness.cli import main
from harness.core.names import file_name
from harness.report.outputs import publish
from harness.report.pageimages import AMPLIFY
from harness.report.record import image_name
from harness.report.results import to_frame, write_results

try:
    from tests.browser import Browser, chromium
except ImportError:  # run from inside tests/
    from browser import Browser, chromium


def _run_folder(tmp_path):
    rows = []
    for m, r, vals in (("random", 0.1, (30.0, 31.0, 29.5)), ("betadesc", 0.1, (32.0, 32.5, 31.0)),
                       ("random", 0.3, (25.0, 26.0, 24.0)), ("betadesc", 0.3, (26.5, 27.0, 25.0)),
                       ("lightgs", 0.1, (math.inf, 197.0, 150.0))):
        for v, p in enumerate(vals):
            rows.append(dict(run="t", scene="sc.a", label="scene <A>", kind="object-centric", frame="", method=m,
                             variant="default", params="{}", ratio=r, keep=round(1 - r, 9), view=f"v{v}", status="ok",
                             psnr=p, ssim=0.95, lpips=0.02, splats_in=100, splats_out=int(100 * (1 - r)), tau=0.5,
                             score_s=0.2))
    df = to_frame(rows)
    write_results(df, tmp_path)
    meta = {"name": "page-test", "commit": "abc123", "when": "2026-01-01T00:00:00", "machine": {"cpus": 2},
            "stage_seconds": {"total": 12.5}, "cache_counts": {"score": {"hits": 1, "misses": 2}},
            "config": {"name": "page-test", "ratios": [0.1, 0.3]}, "tables": ["comparison", "ablation", "versus"],
            "plots": ["curves"], "argv": ["run", "x.yaml"]}
    (tmp_path / "run.json").write_text(json.dumps(meta))
    rng = np.random.default_rng(0)
    ref = (rng.random((48, 64, 3)) * 255).astype(np.uint8)
    d = tmp_path / "images" / "sc.a"
    d.mkdir(parents=True)
    Image.fromarray(ref).save(d / "input.png")
    pruned = {}
    for m, r, delta in (("random", 0.1, 20), ("betadesc", 0.1, 3), ("random", 0.3, 40), ("betadesc", 0.3, 9),
                        ("lightgs", 0.1, 0)):
        img = ref.copy()
        img[10:20, 10:30] = np.clip(img[10:20, 10:30].astype(int) + delta, 0, 255).astype(np.uint8)
        Image.fromarray(img).save(d / image_name(m, "default", r))
        pruned[(m, r)] = img
    return df, meta, ref, pruned


def write_report(run_dir, df, meta):
    """The page as every command writes it (with its tables and plots)."""
    return publish(run_dir, df, meta).page


def _decode(uri: str) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(base64.b64decode(uri.split(",", 1)[1]))).convert("RGB"))


def test_page_is_self_contained_and_its_difference_images_are_faithful(tmp_path):
    df, meta, ref, pruned = _run_folder(tmp_path)
    page = write_report(tmp_path, df, meta).read_text()
    assert not re.search(r"(src|href)=['\"](?!data:|#)", page)  # nothing outside the page
    assert "http://" not in page and "https://" not in page
    assert page.count("type='range' min='0'") == 5  # one slider per scene × method × ratio (+ the width control)
    diffs = re.findall(r"class='diff' alt='difference ([^']*)' src='([^']*)'", page)
    assert len(diffs) == 5
    by_alt = dict(diffs)
    got = _decode(by_alt["BetaDescPrune, 30% pruned"])
    want = np.minimum(255, np.abs(pruned[("betadesc", 0.3)].astype(int) - ref.astype(int)).max(axis=2) * AMPLIFY)
    assert np.array_equal(got[..., 0], want) and np.array_equal(got[..., 1], want)  # lossless, grey
    assert not _decode(by_alt["LightGSPrune, 10% pruned"]).any()  # identical pair: black
    assert "PSNR inf (identical)" in page


def test_page_shows_tables_with_cis_missing_tables_and_the_run_record(tmp_path):
    df, meta, *_ = _run_folder(tmp_path)
    page = write_report(tmp_path, df, meta).read_text()
    assert re.search(r"31\.83<br><small>Δ \+[0-9.]+ \[\+[0-9.]+, \+[0-9.]+\]</small>", page)  # mean, Δ [CI]
    assert "class='better'" in page  # betadesc above random with a CI above 0
    assert "Not made from these results: no ablation variant measured at 20%" in page
    assert "scene &lt;A&gt;" in page and "scene <A>" not in page  # labels escaped
    for text in ("abc123", "page-test", "harness run x.yaml", "1 / 2"):
        assert text in page
    assert f"curves_{file_name('scene <A>')}.png" in page


def test_report_command_writes_the_page(tmp_path, capsys):
    _run_folder(tmp_path)
    assert main(["report", str(tmp_path), "--reference", "betadesc"]) == 0
    assert capsys.readouterr().out.strip() == str(tmp_path / "report.html")
    assert "against BetaDescPrune" in (tmp_path / "report.html").read_text()


@pytest.mark.skipif(chromium() is None, reason="Debian's chromium is not installed (setup.sh installs it)")
def test_page_in_headless_chromium(tmp_path):
    df, meta, *_ = _run_folder(tmp_path)
    page = write_report(tmp_path, df, meta)
    with Browser(width=1280, height=900) as b:
        b.open(page.as_uri())
        b.evaluate("document.querySelectorAll('details').forEach(d => d.open = true)")
        bad = b.evaluate("new Promise(r => setTimeout(() => r(Array.from(document.images)"
                         ".filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.alt)), 300))")
        n_img = b.evaluate("document.images.length")
        clip = b.evaluate(
            "(() => { const s = document.querySelector('.slider input'); s.value = 20;"
            " s.dispatchEvent(new Event('input')); return s.parentNode.querySelector('img').style.clipPath; })()"
        )
        shot = b.screenshot(tmp_path / "shot.png")
        errors = list(b.errors)
    assert errors == []
    assert n_img >= 12 and bad == []  # 5 pruned + 5 differences + reference + curves
    assert clip == "inset(0px 0px 0px 20%)"
    px = np.asarray(Image.open(shot).convert("RGB"))
    assert px.shape[0] > 500 and px.std() > 20 and len(np.unique(px.reshape(-1, 3), axis=0)) > 50  # not blank


def _two_scene_two_protocol_folder(tmp_path):
    """The fixture's results for two scenes and both protocols, with two run records (cold, cached)."""
    df, meta, ref, _ = _run_folder(tmp_path)
    rows = df.to_dict("records")
    more = [{**r, "scene": "sc.b", "label": "scene B", "psnr": r["psnr"] - 1.0} for r in rows]
    both = [{**r, "protocol": p, "view": (f"shifted/{r['view']}" if p == "shifted" else r["view"])}
            for p in ("rig", "shifted") for r in rows + more]
    df = to_frame(both)
    write_results(df, tmp_path)
    d = tmp_path / "images" / "sc.b"
    d.mkdir(parents=True)
    for f in (tmp_path / "images" / "sc.a").iterdir():
        (d / f.name).write_bytes(f.read_bytes())
    (tmp_path / "records").mkdir()
    for when, hits, total in (("2026-01-01T00:00:00", 0, 300.0), ("2026-01-01T00:10:00", 3, 2.0)):
        rec = {**meta, "when": when, "stage_seconds": {"total": total},
               "cache_counts": {"score": {"hits": hits, "misses": 3 - hits}}}
        (tmp_path / "records" / f"{when.replace(':', '')}-1.json").write_text(json.dumps(rec))
    return df, meta


def test_page_summary_first_the_rest_folded_captions_and_every_record(tmp_path):
    """Issue 23, item 6: 31,700 px of tables before the first figure, literal **63.87**, no n, only
    the first scene's images open, the cold run's record overwritten by a cached rerun."""
    df, meta = _two_scene_two_protocol_folder(tmp_path)
    page = write_report(tmp_path, df, meta).read_text()
    body = page[page.index("<main>"):]
    assert body.index("id=\"summary\"") < body.index("id=\"tables\"") < body.index("id=\"images\"")
    summary = body[body.index("id=\"summary\""):body.index("id=\"tables\"")]
    assert "held-out views: rig" in summary and "held-out views: shifted" in summary  # one headline per protocol
    rest = body[body.index("id=\"tables\""):]
    assert "<details open" not in rest  # everything after the summary is folded
    for key in ("comparison", "comparison-shifted", "ablation", "ablation-shifted", "versus", "versus-shifted"):
        assert f"<details id='t-{key}'>" in rest
    tables = re.findall(r"<table>(.*?)</table>", page, re.S)
    assert tables and all("<caption>n = " in t for t in tables)  # n (and the interval) on every data table
    assert all("Student-t" in t for t in tables if "Δ" in t)
    assert "**" not in re.sub(r"<[^>]+>", "", page)  # no markdown syntax shown
    for scene in ("sc.a", "sc.b"):  # every scene's images reachable from the index
        assert f"<a href='#img-{scene}'>" in page and f"<details id='img-{scene}'>" in page
    records = re.search(r"<h2 id=\"record\">.*", page, re.S).group(0)
    assert "2 run(s) into this folder" in records and "300.0" in records and "0 / 3" in records and "3 / 0" in records
    assert "not run" not in page


def test_without_a_lead_table_no_bottom_line_and_the_headline_per_protocol():
    from harness.report.page import summary_html
    from harness.report.tabledata import Built, Table

    disp = pd.DataFrame({"psnr": ["30.00 (Δ +1.00 [+0.50, +1.50])"]}, index=pd.Index(["betadesc"], name="method"))
    comp = Built("comparison", "comparison", "rig", "Comparison — held-out views: rig",
                 Table(disp, [], disp.reset_index(), caption="n = 2"))
    bottom, summary = summary_html({"comparison": comp})
    assert bottom == "" and "Comparison — held-out views: rig" in summary and "class='better'" in summary


@pytest.mark.skipif(chromium() is None, reason="Debian's chromium is not installed (setup.sh installs it)")
@pytest.mark.parametrize("width", [1280, 1920])
def test_no_table_is_wider_than_the_page_and_links_open_their_section(tmp_path, width):
    df, meta = _two_scene_two_protocol_folder(tmp_path)
    page = write_report(tmp_path, df, meta)
    with Browser(width=width, height=900) as b:
        b.open(page.as_uri())
        b.evaluate("location.hash = 'img-sc.b'")
        opened = b.evaluate("new Promise(r => setTimeout(() => r(document.getElementById('img-sc.b').open), 200))")
        b.evaluate("document.querySelectorAll('details').forEach(d => d.open = true)")
        over = b.evaluate(
            "Array.from(document.querySelectorAll('.scroll, table')).filter(e => "
            "e.closest('.scroll') === e || !e.closest('.scroll')).map(e => e.getBoundingClientRect().right)"
            ".filter(r => r > window.innerWidth + 1).length"
        )
        doc = b.evaluate("document.documentElement.scrollWidth")
        errors = list(b.errors)
    assert opened is True and over == 0 and doc == width and errors == []


@pytest.mark.skipif(chromium() is None, reason="Debian's chromium is not installed (setup.sh installs it)")
@pytest.mark.parametrize("width", [1280, 1920])
def test_page_opens_with_the_bottom_line_and_colours_claims_by_verdict(tmp_path, width):
    """A study's page: the bottom line is the first thing in it, a failing claim's cells are red
    although its Δ is positive on most scenes, the evidence column is the wide one."""
    from tests.test_claims import _study
    from tests.test_page_lead import two_protocols

    df = two_protocols(_study(gains={"s3": -3.0}))  # t2-descriptors: +2 dB on four scenes, -3 on one: fails
    write_results(df, tmp_path)
    meta = {"name": "claims", "commit": "abc", "when": "2026-01-01T00:00:00", "tables": ["claims", "comparison"],
            "plots": [], "argv": ["run", "x.yaml"]}
    (tmp_path / "run.json").write_text(json.dumps(meta))
    page = write_report(tmp_path, df, meta)
    with Browser(width=width, height=900) as b:
        b.open(page.as_uri())
        first = b.evaluate("document.querySelector('main').firstElementChild.id")
        top = b.evaluate("document.getElementById('bottom-line').getBoundingClientRect().bottom")
        cell = b.evaluate("(() => { const a = document.getElementById('lead-rig-t2-descriptors');"
                          " const td = a.closest('tr').children[1];"
                          " return [td.className, getComputedStyle(td).backgroundColor, td.textContent]; })()")
        widths = b.evaluate("Array.from(document.querySelectorAll('table.lead')[0].rows[0].cells)"
                            ".map(c => Math.round(c.getBoundingClientRect().width))")
        folded = b.evaluate("document.getElementById('s-shifted').open")
        errors = list(b.errors)
    assert first == "bottom-line" and 0 < top < 400 and errors == []
    assert cell[0] == "v v-fails" and cell[1] == "rgb(245, 201, 201)" and cell[2].startswith("fails")
    assert widths[-1] > 2 * max(widths[1:-1]) and widths[-1] > widths[0]  # evidence wide, verdicts narrow
    assert folded is False  # the other protocol's claims are folded
