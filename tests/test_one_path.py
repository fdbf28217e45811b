"""One path from results to every output (issue 23, item 1): `harness run`, `harness tables` and
`harness report` write the same tables and the same page, per held-out view protocol, each labelled.

Before, `harness report` pooled the rig and shifted protocols into one table without saying so
(grape-small BetaDescPrune at 10 %: 62.34 on its page, 62.85 in comparison.md and 61.82 in
comparison-shifted.md) and dropped every -shifted table. Here a real two-protocol run (GL renderer,
two small scenes) goes through all three commands and the outputs are compared byte for byte; the
page's numbers are checked against the .md tables they must show.
"""

from __future__ import annotations

import html
import re
import shutil
from collections import Counter

import pytest
import yaml

from harness.cli import main
from tests import runner_fakes as fakes
from tests.gl_support import require_gl

_NUM = re.compile(r"[+-]?\d+\.\d+")


def _config(tmp_path, scenes) -> str:
    doc = {"name": "two-protocols", "protocol": {"longest_side": 32, "metrics": ["psnr", "ssim"], "n_train": 3,
                                                 "n_test": 2},
           "protocols": ["rig", "shifted"], "ratios": [0.1, 0.3],
           "scenes": [{"name": k, "source": v} for k, v in scenes.items()],
           "methods": ["opacity", "random"], "tables": ["comparison", "versus", "runtime"], "plots": ["curves"]}
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(doc))
    return str(path)


def _page_tables(page: str) -> dict[str, str]:
    """{table key: the text of its folded block} of a report page."""
    return {m.group(1): m.group(2) for m in re.finditer(r"<details id='t-([^']+)'>(.*?)</details>", page, re.S)}


def _numbers(text: str) -> Counter:
    return Counter(_NUM.findall(html.unescape(re.sub(r"<[^>]+>", " ", text))))


@pytest.mark.gl
def test_run_tables_and_report_write_the_same_outputs_per_protocol(tmp_path, capsys):
    require_gl()
    scenes = fakes.write_two_scenes(tmp_path)
    run = tmp_path / "run"
    assert main(["run", _config(tmp_path, scenes), "--out", str(run), "--cache", str(tmp_path / "cache")]) == 0
    capsys.readouterr()
    by_tables, by_report = tmp_path / "by-tables", tmp_path / "by-report"
    shutil.copytree(run, by_tables)
    shutil.copytree(run, by_report)
    for folder in (by_tables, by_report):  # nothing left from the run: each command writes everything
        shutil.rmtree(folder / "tables")
        shutil.rmtree(folder / "plots")
        (folder / "report.html").unlink()
    assert main(["tables", str(by_tables)]) == 0
    assert main(["report", str(by_report)]) == 0

    names = sorted(p.name for p in (run / "tables").iterdir())
    assert {"comparison.md", "comparison-shifted.md", "versus.csv", "versus-shifted.csv", "runtime-shifted.tex",
            "summary.csv"} <= set(names)
    for other in (by_tables, by_report):
        assert sorted(p.name for p in (other / "tables").iterdir()) == names
        for name in names:  # byte-identical tables
            assert (other / "tables" / name).read_bytes() == (run / "tables" / name).read_bytes(), name
        assert (other / "report.html").read_text() == (run / "report.html").read_text()

    # every table is labelled with its protocol, the primary one too
    for name in names:
        if name.endswith(".md"):
            head = (run / "tables" / name).read_text().splitlines()[0]
            assert ("held-out views: shifted" in head) == ("-shifted" in name), (name, head)
            assert "held-out views: rig" in head or "-shifted" in name
    assert set((run / "tables" / "summary.csv").read_text().splitlines()[0].split(",")) >= {"protocol", "psnr_std"}

    # the page shows each table's own numbers: same multiset of numbers as its .md
    page = (run / "report.html").read_text()
    blocks = _page_tables(page)
    assert {"comparison", "comparison-shifted", "versus", "versus-shifted"} <= set(blocks)
    for key, block in blocks.items():
        md = (run / "tables" / f"{key}.md").read_text()
        assert _numbers(block) == _numbers(md), key
    assert "held-out views: rig" in page and "held-out views: shifted" in page


def test_a_misspelt_scene_stops_the_run_before_it_touches_the_folder(tmp_path, capsys):
    """Issue 23, item 2: `name: luigii` printed a skip, exited 0 and left tables/ holding only
    summary.csv. Now: one line with the known names and "did you mean", exit 2, nothing written."""
    out = tmp_path / "run"
    (out / "tables").mkdir(parents=True)
    (out / "tables" / "comparison.md").write_text("an earlier run's table")
    (out / "results.parquet").write_bytes(b"earlier results")
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    cfg = tmp_path / "typo.yaml"
    cfg.write_text(yaml.safe_dump({"scenes": [{"name": "luigii"}], "methods": ["opacity"], "ratios": [0.1]}))
    assert main(["run", str(cfg), "--out", str(out), "--cache", str(tmp_path / "cache")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "scenes[0] 'luigii': unknown scene name 'luigii' (did you mean 'luigi'?); " \
        "known: " in err, err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    assert not (tmp_path / "cache").exists()


def test_a_run_that_measures_nothing_replaces_nothing(tmp_path, capsys):
    """Every scene optional and absent: the skip is said, the earlier outputs stay, the record is kept."""
    out = tmp_path / "run"
    (out / "tables").mkdir(parents=True)
    (out / "tables" / "comparison.md").write_text("an earlier run's table")
    (out / "results.parquet").write_bytes(b"earlier results")
    cfg = tmp_path / "absent.yaml"
    cfg.write_text(yaml.safe_dump({"scenes": [{"name": "mpeg", "sequence": str(tmp_path / "nope"), "optional": True}],
                                   "methods": ["opacity"], "ratios": [0.1]}))
    assert main(["run", str(cfg), "--out", str(out), "--cache", str(tmp_path / "cache")]) == 0
    text = capsys.readouterr().out
    assert "skipped mpeg: sequence folder not found" in text and "nothing measured" in text
    assert (out / "tables" / "comparison.md").read_text() == "an earlier run's table"
    assert (out / "results.parquet").read_bytes() == b"earlier results"
    assert len(list((out / "records").glob("*.json"))) == 1 and not (out / "run.json").exists()
