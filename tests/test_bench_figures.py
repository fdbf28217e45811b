"""The plan figures the docs quote live in committed files that the code still writes:
`harness plan CONFIG --estimate` with the committed unit costs (``results/bench``), byte for byte,
paths of this checkout aside. When the model or the units change, regenerate them:

    harness plan ctc_configs/default.yaml --estimate > results/bench/plan-default.md
    harness plan ctc_configs/ctc.yaml --estimate --workers 128 > results/bench/plan-ctc.md

(with this checkout's path replaced by ``.``)."""

from __future__ import annotations

import pytest

from harness.cli import main
from harness.core.paths import REPO_ROOT

CASES = {"plan-default.md": ["ctc_configs/default.yaml"], "plan-ctc.md": ["ctc_configs/ctc.yaml", "--workers", "128"]}


@pytest.mark.parametrize("name", CASES)
def test_the_committed_plan_is_what_plan_prints(name, monkeypatch, capsys):
    committed = (REPO_ROOT / "results" / "bench" / name).read_text()
    monkeypatch.chdir(REPO_ROOT)
    assert main(["plan", *CASES[name], "--estimate"]) == 0
    out = capsys.readouterr().out.replace(f"{REPO_ROOT}/", "./")
    first = committed.split("\n\n")[1].split(";")[0]  # "N scenes (r read, a assumed)"
    if first not in out:
        pytest.skip(f"the scenes here are not the committed plan's ({first}): harness fetch")
    assert out == committed, f"results/bench/{name} is stale: regenerate it (this module's docstring)"
