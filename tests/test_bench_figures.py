"""The plan figures the docs quote live in committed files that the code still writes:
`harness plan CONFIG --estimate` with the committed unit costs (``results/bench``), byte for byte,
paths of this checkout aside. When the model or the units change, regenerate them:

    harness plan ctc_configs/default.yaml --estimate > results/bench/plan-default.md
    harness plan ctc_configs/full.yaml --estimate > results/bench/plan-full.md
    harness plan ctc_configs/ctc.yaml --estimate --workers 128 > results/bench/plan-ctc.md

(with this checkout's path replaced by ``.``)."""

from __future__ import annotations

import re

import pytest

from harness.cli import main
from harness.core.paths import REPO_ROOT

CASES = {"plan-default.md": ["ctc_configs/default.yaml"], "plan-full.md": ["ctc_configs/full.yaml"],
         "plan-ctc.md": ["ctc_configs/ctc.yaml", "--workers", "128"]}


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


PLAN_DOC = REPO_ROOT / "docs" / "plan.md"
NUMBER = re.compile(r"\d+(?:,\d{3})*(?:\.\d+)?")


def _citing(text: str) -> list[tuple[set, str]]:
    """(files, text) of each paragraph and table row of a page that names ``results/bench`` files;
    a table's rows that name none stand on the files of the paragraph before the table."""
    out, before = [], set()
    for block in re.split(r"\n\s*\n", text):
        if not block.lstrip().startswith("|"):
            before = {n for n in re.findall(r"results/bench/([\w.-]+\.md)", block)} | \
                {n for n in re.findall(r"`(calibrate-check-[\w.-]+\.md)`", block)}
            out += [(before, block)] if before else []
            continue
        for row in block.splitlines():
            files = set(re.findall(r"results/bench/([\w.-]+\.md)", row)) or before
            if files:
                out.append((files, row))
    return out


def test_the_plan_page_quotes_its_figures_from_the_committed_files():
    cited = _citing(PLAN_DOC.read_text())
    assert len(cited) >= 6, "docs/plan.md names fewer plan and check files than it should"
    for files, text in cited:
        printed = set(NUMBER.findall("\n".join((REPO_ROOT / "results" / "bench" / f).read_text() for f in files)))
        for f in files:
            text = text.replace(f, "")
        missing = [n for n in NUMBER.findall(text) if n not in printed]
        assert not missing, f"docs/plan.md quotes {missing} that {sorted(files)} do not print, in: {text[:120]!r}"
