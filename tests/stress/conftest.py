"""Stress-suite settings: case budgets per mode, per-family case counters, and the counts report.

Mode: ``HARNESS_STRESS=full`` is the real stress run (≥ 10,000 reader-fuzzer cases, thousands of
Hypothesis examples); anything else is the bounded CI mode (the whole folder in a few minutes on two
cores). Every module here sets ``pytestmark = pytest.mark.stress``.

Each family adds the cases it tried to the session counter (``stress_counts`` fixture:
``stress_counts.add("readers", loaded=3, clean_error=5)``; sizes that are not case counts
go through ``stress_counts.note(family, key, value)``). At the end of the session the counts and
the wall time are printed and written as JSON — to ``results/stress/counts.json`` in full mode (the
report the project keeps), to ``<pytest tmp dir>/stress-counts.json`` in CI mode, so a CI run never
dirties the repository.
"""

from __future__ import annotations

import json
import time
from collections import defaultdict
from pathlib import Path

import pytest

from tests.stress.budget import FULL, mode

_COUNTS: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
_START = time.time()


class _Counter:
    def add(self, family: str, **outcomes: int) -> None:
        for k, v in outcomes.items():
            _COUNTS[family][k] += int(v)
        _COUNTS[family]["cases"] += int(sum(outcomes.values()))

    def note(self, family: str, key: str, value: int) -> None:
        """A size worth reporting (e.g. splats in one case) that is not a count of cases."""
        _COUNTS[family][key] = max(_COUNTS[family][key], int(value))


@pytest.fixture(scope="session")
def stress_counts() -> _Counter:
    return _Counter()


def _report_path(config) -> Path:
    # only a whole full run (no -k selection) replaces the kept report
    if FULL and not config.option.keyword:
        from harness.core.paths import results_dir

        return results_dir() / "stress" / "counts.json"
    return Path(config._tmp_path_factory.getbasetemp()) / "stress-counts.json"


def pytest_sessionfinish(session, exitstatus):
    if not _COUNTS:
        return
    payload = {"mode": mode(), "wall_s": round(time.time() - _START, 1), "exit_status": int(exitstatus),
               "when": time.strftime("%Y-%m-%dT%H:%M:%S"),
               "families": {f: dict(sorted(c.items())) for f, c in sorted(_COUNTS.items())}}
    path = _report_path(session.config)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(payload, indent=2) + "\n")
    tmp.replace(path)
    session.config._stress_report = (path, payload)


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    report = getattr(config, "_stress_report", None)
    if report is None:
        return
    path, payload = report
    terminalreporter.section(f"stress cases ({payload['mode']} mode, {payload['wall_s']} s)")
    for family, counts in payload["families"].items():
        rest = ", ".join(f"{k} {v}" for k, v in counts.items() if k != "cases")  # includes notes
        terminalreporter.write_line(f"{family:<12} {counts['cases']:>7} cases  ({rest})")
    terminalreporter.write_line(f"written to {path}")
