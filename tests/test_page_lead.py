"""The report page's lead: verdict statuses, the bottom line, the lead table (harness/report/verdicts.py,
pagelead.py), and the study's claims table filling them (harness/study/claims_lead.py), on synthetic
claims whose verdicts are known."""

from __future__ import annotations

import re
from html import unescape

import pandas as pd
import pytest

from harness.report import pagelead
from harness.report.verdicts import FAILS, HOLDS, MIXED, NOT_TESTABLE, UNCLEAR, Item, Lead, compare
from harness.study import claims, rules
from harness.study.claims_lead import LEAD, claim_items, status_of

try:
    from tests.test_claims import _study
except ImportError:  # run from inside tests/
    from test_claims import _study


def _item(key, status, **kw):
    return Item(key=key, what=f"claim {key}", status=status, verdict=status, **kw)


LEAD_ABC = Lead(items=list, noun=("claim", "claims"), phrases={MIXED: ("depends on the reading", "depend on it")})


def test_every_study_verdict_is_one_status_and_other_cells_are_none():
    assert {status_of(v) for v in rules.VERDICTS} == {"holds", "fails", "inconclusive", "underpowered",
                                                      "not testable", "not comparable"}
    assert status_of(claims.DEPENDS) == MIXED
    assert status_of("fails (direction: inconclusive, size: fails)") == FAILS
    assert status_of("inconclusive (paper-literal only)") == UNCLEAR
    for cell in ("Table 1: competitive with camera-aware pruning (L323)", "S1 +2.00 [+1.8, +2.2] ✓", "–", ""):
        assert status_of(cell) is None


def test_an_item_refuses_a_status_outside_the_vocabulary():
    with pytest.raises(ValueError, match="'supported' is not one of holds, fails"):
        _item("a", "supported")


def test_bottom_line_counts_names_and_says_how_another_protocol_differs():
    main = [_item("a", HOLDS), _item("b", FAILS), _item("c", FAILS), _item("d", MIXED), _item("e", NOT_TESTABLE)]
    other = [_item("a", HOLDS), _item("b", HOLDS), _item("c", NOT_TESTABLE), _item("d", MIXED), _item("e", HOLDS)]
    text = pagelead.bottom_line("rig", main, LEAD_ABC, {"shifted": other, "independent": None})
    plain = re.sub(r"<[^>]+>", "", text)
    assert plain.startswith("Bottom line, under the rig views: of 5 claims, 1 holds (a); 2 fail (b, c); "
                            "1 depends on the reading (d); 1 is not testable here (e).")
    assert "shifted agrees on 2 of 3 and differs on 1 (b holds) (1 more not testable there)" in plain
    assert "independent has no verdicts" in plain
    assert "<span class='v v-fails'>2 fail</span>" in text and "href='#lead-rig-b'" in text
    assert compare("x", main, other).changed == (("b", HOLDS),)


def test_lead_table_colours_by_verdict_and_folds_the_untestable_into_one_line():
    items = [_item("up", FAILS, facets=(("r1", FAILS, "fails"), ("r2", HOLDS, "holds")),
                   evidence=(("r1", ("S1 +94.0 [+80.1, +107.9] ✗", "S2 +3.1 [+2.0, +4.2] ✓")),)),
             _item("gone", NOT_TESTABLE, note="no cell"), _item("gone2", NOT_TESTABLE, note="no other cell")]
    html = pagelead.lead_table(items, LEAD_ABC, "rig")
    row = re.search(r"<tr><td class='what'><a id='lead-rig-up'.*?</tr>", html).group(0)
    verdict, r1, r2 = re.findall(r"<td class='(v [^']+)'>", row)
    assert (verdict, r1, r2) == ("v v-fails", "v v-fails", "v v-holds")  # a positive Δ that fails is red
    assert "better" not in html and "worse" not in html
    assert "<span class='c'>S1 +94.0 [+80.1, +107.9] <b class='m-fails'>✗</b></span>" in row
    assert html.count("<tr>") == 1 + 1  # header and the one testable claim: the untestable are no rows
    note = re.search(r"<details class='untestable'><summary>(.*?)</summary>", html).group(1)
    assert note == "2 claims are not testable here: gone, gone2"
    assert "<b>gone</b> claim gone: no cell" in html


def test_claim_items_of_a_claims_table():
    table = claims.table_claims(_study(gains={"s3": -3.0}), overhead={})
    items = {i.key: i for i in claim_items(table)}
    assert list(items) == list(table.sections[0][1].index)  # every claim, in the paper's order
    one = items["t2-descriptors"]  # 4 scenes hold, one fails beyond Holm
    assert one.status == FAILS and one.verdict == "fails (paper-literal only)"
    assert [f[:2] for f in one.facets] == [("paper-literal", FAILS), ("paper-direction", NOT_TESTABLE)]
    assert one.detail.startswith(f"paper: {table.sections[0][1].loc['t2-descriptors', 'paper']} · universal")
    label, chunks = one.evidence[0]
    assert label == "paper-literal" and len(chunks) == 5 and chunks[2].startswith("S3 ") and chunks[2].endswith("✗")
    runtime = items["runtime-added"]  # no overhead measured: not testable, said why, no numbers
    assert runtime.status == NOT_TESTABLE and runtime.evidence == () and "paper-literal: " in runtime.note
    assert items["t1-competitive-10%"].status == HOLDS


def test_the_study_registers_claims_as_the_page_lead():
    from harness.report.tables import TABLE_SPECS

    spec = TABLE_SPECS.get("claims")
    assert spec.lead is LEAD and spec.verdicts is status_of
    assert TABLE_SPECS.get("findings").verdicts is status_of and TABLE_SPECS.get("findings").lead is None


def two_protocols(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` under the rig and the shifted protocol (the same numbers)."""
    return pd.concat([df.assign(protocol="rig"), df.assign(protocol="shifted", view="shifted/" + df["view"])],
                     ignore_index=True)


def test_summary_leads_with_the_main_protocols_claims_and_folds_the_others(tmp_path):
    from harness.report.page import summary_html
    from harness.report.tables import write_tables

    built = write_tables(two_protocols(_study(gains={"s3": -3.0})), tmp_path, ["claims", "comparison"]).built
    bottom, summary = summary_html(built)
    assert bottom.startswith("<p class='bottom' id='bottom-line'><b>Bottom line</b>, under the rig views")
    assert "shifted agrees on all" in bottom
    lead = summary.index("<table class='lead'>")
    assert lead < summary.index("Comparison") < summary.index("<details id='s-shifted'>")
    assert summary.count("<table class='lead'>") == 2  # the shifted protocol's, folded


def test_a_lead_whose_items_are_invalid_leads_nothing_and_says_why(monkeypatch):
    from harness.report.page import summary_html
    from harness.report.tabledata import Built, Table
    from harness.report.tables import TABLE_SPECS, TableSpec

    def bad(table):
        return [_item("a", "supported")]

    TABLE_SPECS.get("claims")  # the registry loaded, then one more entry, taken out after the test
    spec = TableSpec("bad-lead", bad, "Bad", verdicts=status_of, lead=Lead(items=bad))
    monkeypatch.setitem(TABLE_SPECS._entries, "bad-lead", spec)
    disp = pd.DataFrame({"verdict": ["supported"]}, index=pd.Index(["a"], name="key"))
    bottom, summary = summary_html({"bad-lead": Built("bad-lead", "bad-lead", "rig", "Bad", Table(disp, [], disp))})
    assert bottom == ""
    assert "the bad-lead table cannot lead this page: item 'a': status 'supported'" in unescape(summary)
