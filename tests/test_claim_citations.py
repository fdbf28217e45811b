"""Every claim of the claims table cites the paper where its words and numbers are: its quote is in the
LaTeX source within ±2 lines of a cited line, and so is every number it takes from the paper."""

from __future__ import annotations

from pathlib import Path

import pytest

from harness.study.claim_list import CLAIMS

PAPER = Path(__file__).resolve().parent.parent.parent / "shared" / "paper" / "000_c1a9120657c37710.txt"


@pytest.fixture(scope="module")
def lines() -> list[str]:
    if not PAPER.exists():
        pytest.skip(f"the paper's LaTeX source is not at {PAPER}")
    return PAPER.read_text().splitlines()


def _near(lines: list[str], cited: tuple[int, ...], text: str) -> bool:
    """``text`` on a line within ±2 of one of the ``cited`` (1-based) lines."""
    return any(text in lines[i - 1] for c in cited for i in range(max(1, c - 2), min(len(lines), c + 2) + 1))


@pytest.mark.parametrize("claim", CLAIMS, ids=lambda c: c.key)
def test_quote_and_numbers_are_where_the_claim_cites_them(lines, claim):
    assert _near(lines, claim.lines, claim.quote), f"{claim.key}: quote not within ±2 lines of {claim.lines}"
    for number in claim.numbers:
        assert _near(lines, claim.lines, number), f"{claim.key}: {number} not within ±2 lines of {claim.lines}"
    assert claim.lines[0] in range(1, len(lines) + 1)


def test_the_first_cited_line_is_the_sentence_not_markup(lines):
    for claim in CLAIMS:
        first = lines[claim.lines[0] - 1].strip()
        assert not first.startswith("\\") and len(first) > 80, f"{claim.key}: L{claim.lines[0]} is {first[:40]!r}"


def test_a_wrong_citation_is_caught(lines):
    """The check can fail: the old citation of Table 1's claim (L327, a \\begin{center}) misses its sentence."""
    claim = next(c for c in CLAIMS if c.key == "t1-competitive-20%")
    assert not _near(lines, (330,), claim.quote)
    assert lines[327 - 1].strip() == "\\begin{center}"
