"""The study's publisher: results/<name>/README.md generated from the run's record, naming the verdict
rules' commit and whether the run came after it."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from harness.study import publish

REPO = Path(__file__).resolve().parents[1]


def _head() -> str:
    return subprocess.run(["git", "-C", str(REPO), "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()


def _run_dir(tmp_path: Path, commit: str, when: str, hits: int = 0) -> Path:
    run = tmp_path / "run"
    (run / "tables").mkdir(parents=True)
    for name in ("claims.md", "claims.csv", "claims-shifted.md", "comparison.md", "findings.md"):
        (run / "tables" / name).write_text(name)
    (run / "views.csv.gz").write_bytes(b"\x1f\x8b")
    (run / "run.json").write_text(json.dumps({
        "name": "default", "commit": commit, "when": when, "workers": 2, "argv": ["run", "ctc_configs/default.yaml"],
        "machine": {"cpus": 2, "cuda": None, "platform": "Linux"}, "cpu_seconds": 2600.4,
        "stage_seconds": {"score": 300.0, "render_metrics": 1000.0, "total": 1500.2},
        "cache_counts": {"load": {"hits": hits, "misses": 5}}}))
    return run


def test_rules_commit_is_read_from_the_pre_registration_record():
    full, when = publish.rules_commit()
    assert len(full) == 40 and when.startswith("20")


def test_a_published_run_names_the_rules_and_says_it_came_after(tmp_path):
    head = _head()
    if not head:
        pytest.skip("not a git checkout: the commit order cannot be checked")
    dest = tmp_path / "results"
    dest.mkdir()
    (dest / "stale.md").write_text("a table the run no longer makes")
    names = publish.publish(_run_dir(tmp_path, head, "2099-01-01T00:00:00"), dest)
    assert "claims.md" in names and "views.csv.gz" in names and not (dest / "stale.md").exists()
    text = (dest / "README.md").read_text()
    rules, _ = publish.rules_commit()
    assert f"`{rules[:12]}`" in text and "descends from it" in text and "ran after them" in text
    assert "**cold** stage cache" in text and "Wall time 25 min 00 s" in text and "`shifted`" in text


def test_a_cached_run_before_the_rules_says_so(tmp_path):
    rules, _ = publish.rules_commit()
    first = subprocess.run(["git", "-C", str(REPO), "rev-list", "--max-parents=0", "HEAD"],
                           capture_output=True, text=True).stdout.split()
    if not first:
        pytest.skip("not a git checkout: the commit order cannot be checked")
    dest = tmp_path / "results"
    publish.publish(_run_dir(tmp_path, first[0], "2020-01-01T00:00:00", hits=7), dest)
    text = (dest / "README.md").read_text()
    assert "does NOT descend from it" in text and "ran BEFORE them" in text and "7 hits" in text


def test_a_folder_without_a_run_record_is_refused_in_one_line(tmp_path):
    done = subprocess.run([sys.executable, "-m", "harness.study.publish", str(tmp_path), str(tmp_path / "out")],
                          capture_output=True, text=True, cwd=REPO)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "no run.json" in done.stderr
    assert not (tmp_path / "out").exists()


def test_the_committed_default_results_readme_is_the_generated_one():
    dest = REPO / "results" / "default"
    if not (dest / "run.json").exists():
        pytest.skip("results/default has no run.json: the default study has not been published by the publisher")
    run = json.loads((dest / "run.json").read_text())
    if publish.descends(run["commit"], publish.rules_commit()[0]) is None:
        pytest.skip("git cannot tell the commits' order here (no history): the README's order line differs")
    assert (dest / "README.md").read_text() == publish.readme(run, publish.listing(dest), publish.rules_commit())
