"""Issue 15's case table as tests: every hostile-user case (tests/stress/cases.py) through the
real CLI in a subprocess, with a time and memory limit; each must end as the case wants (one clean
line and exit 2, inputs unchanged, nothing half-written; or success with valid JSON). The studies
that run a whole `harness run` are marked slow."""

from __future__ import annotations

import pytest

from tests.stress.cases import CASES, run_case

pytestmark = [pytest.mark.stress]


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id, marks=[pytest.mark.slow] if c.slow else [])
                                  for c in CASES])
def test_case(case, tmp_path, stress_counts):
    result = run_case(case, work=tmp_path)
    if result["outcome"].startswith("skipped"):
        pytest.skip(result["outcome"])
    stress_counts.add("cli cases", **{"as wanted" if result["outcome"] == case.want else "wrong": 1})
    assert result["outcome"] == case.want, result
