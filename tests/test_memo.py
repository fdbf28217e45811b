"""Tables and plots are rebuilt only when their inputs changed (harness.report.memo): the page drawn
from kept tables is the page drawn from rebuilt ones, and any change — results, options, code, a
file edited or removed, a damaged memo — rebuilds."""

from __future__ import annotations

import json

import pytest

from harness.report import memo, outputs
from harness.report.results import write_results
from harness.report.tracking import read_run
from tests.test_tables import _rows


@pytest.fixture
def run_dir(tmp_path):
    write_results(_rows(), tmp_path)
    (tmp_path / "run.json").write_text(json.dumps({"name": "t", "tables": ["comparison", "ablation", "keep"],
                                                   "plots": ["curves"]}))
    return tmp_path


def _publish(run_dir, **options):
    df, meta = read_run(run_dir)
    return outputs.publish(run_dir, df, meta, **options)


def _forbid_building(monkeypatch):
    def fail(*a, **k):
        raise AssertionError("rebuilt although nothing changed")
    monkeypatch.setattr(outputs, "write_tables", fail)
    monkeypatch.setattr(outputs, "write_plots", fail)


def test_a_rerun_keeps_tables_and_plots_and_draws_the_same_page(run_dir, monkeypatch):
    first = _publish(run_dir)
    page, files = first.page.read_bytes(), {p: p.read_bytes() for p in first.written.paths}
    assert any(p.suffix == ".png" for p in files) and (run_dir / memo.FOLDER / memo.NAME).is_file()
    with monkeypatch.context() as m:
        _forbid_building(m)
        again = _publish(run_dir)
    assert again.page.read_bytes() == page
    assert sorted(again.written.paths) == sorted(files) and all(p.read_bytes() == b for p, b in files.items())
    assert again.written.missing == first.written.missing and again.written.warnings == first.written.warnings


@pytest.mark.parametrize("change", ["results", "options", "edited file", "removed file", "damaged memo", "code"])
def test_any_change_rebuilds(run_dir, monkeypatch, tmp_path_factory, change):
    first = _publish(run_dir)
    calls = []
    real = outputs.write_tables
    monkeypatch.setattr(outputs, "write_tables", lambda *a, **k: calls.append(1) or real(*a, **k))
    options = {}
    if change == "results":
        df, _ = read_run(run_dir)
        df.loc[df.index[0], "psnr"] += 1.0
        write_results(df, run_dir)
    elif change == "options":
        options = {"reference": "betadesc-nodesc"}
    elif change == "edited file":
        (run_dir / "tables" / "comparison.md").write_text("edited")
    elif change == "removed file":
        next(p for p in first.written.paths if p.suffix == ".png").unlink()
    elif change == "damaged memo":
        (run_dir / memo.FOLDER / memo.NAME).write_text("{not json")
    else:
        extra = tmp_path_factory.mktemp("code") / "builder.py"
        extra.write_text("X = 1\n")
        files = memo.code_files()
        monkeypatch.setattr(memo, "code_files", lambda: [*files, extra])
        _publish(run_dir)  # a memo under the digest with this file ...
        extra.write_text("X = 2\n")  # ... then the code changes
        calls.clear()
    _publish(run_dir, **options)
    assert calls == [1]
    assert (run_dir / "tables" / "comparison.md").read_text() != "edited"


def test_the_code_digest_covers_the_table_builders_and_the_page():
    names = {f.name for f in memo.code_files()}
    assert {"outputs.py", "tables.py", "cells.py", "stats.py", "plots.py", "page.py", "registry.py"} <= names


def test_a_table_that_does_not_survive_json_is_not_kept(run_dir, monkeypatch):
    """The memo is checked against the tables it keeps: one that would come back different (here:
    any) leaves no memo, and the next publish rebuilds."""
    monkeypatch.setattr(memo, "_same_frame", lambda a, b: False)
    _publish(run_dir)
    assert not (run_dir / memo.FOLDER / memo.NAME).exists()
