"""The paper study plugs in as a third party does: its table and its benchmarks come through entry
points, and a benchmark of another installed package is a ``harness bench`` sub-command too."""

from __future__ import annotations

from importlib.metadata import entry_points

import pytest

from harness.cli import main
from harness.commands.bench import benchmarks

REINSTALL = "the installed metadata is older than pyproject.toml: .venv/bin/python -m pip install -e . --no-deps"


def test_the_study_is_named_by_entry_points_only():
    tables = {ep.value for ep in entry_points(group="harness.tables")}
    benches = {ep.name: ep.value for ep in entry_points(group="harness.benchmarks")}
    assert "harness.study.tables" in tables, REINSTALL
    assert {n: benches.get(n) for n in ("reading", "virtualrig", "tradeoff")} == {
        n: f"harness.study.bench.{n}" for n in ("reading", "virtualrig", "tradeoff")}, REINSTALL


def test_the_claims_table_is_registered_through_its_entry_point():
    from harness.report.tables import TABLE_SPECS
    from harness.study.claims import table_claims

    assert TABLE_SPECS.get("claims").build is table_claims


def _install(tmp_path, monkeypatch, entries: str, modules: dict[str, str]) -> None:
    """A distribution ``bench-plugin`` in ``tmp_path`` (on sys.path) with ``harness.benchmarks`` ``entries``."""
    for name, text in modules.items():
        (tmp_path / f"{name}.py").write_text(text)
    dist = tmp_path / "bench_plugin-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: bench-plugin\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[harness.benchmarks]\n" + entries)
    monkeypatch.syspath_prepend(str(tmp_path))


BENCH = '''
HELP = "count to three"


def add_arguments(parser):
    parser.add_argument("--to", type=int, default=3)


def run(args):
    print("counted", list(range(1, args.to + 1)), "into", args.out)
    return 0
'''


def test_a_third_party_benchmark_runs_and_bad_entries_are_one_line_each(tmp_path, monkeypatch, capsys):
    _install(tmp_path, monkeypatch, "count = count_bench\nread = count_bench\nghost = no_such_module\n",
             {"count_bench": BENCH})
    found = {e.name: e for e in benchmarks()}
    err = capsys.readouterr().err
    assert found["count"].help == "count to three" and found["count"].module == "count_bench"
    assert found["read"].module == "harness.benchmarks.read"  # a built-in's name stays the built-in's
    assert "ghost" not in found
    assert "entry point read = count_bench (harness.benchmarks) skipped: the name is taken" in err
    assert "entry point ghost = no_such_module (harness.benchmarks) skipped: no module no_such_module" in err
    assert main(["bench", "count", "--to", "2", "--out", str(tmp_path / "o")]) == 0
    assert f"counted [1, 2] into {tmp_path / 'o'}" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["bench", "count", "--help"])
    assert "count to three" in capsys.readouterr().out
