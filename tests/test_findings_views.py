"""The findings table (generated from the claims table's rows) and views.csv.gz (the per-view
measurements a run writes beside its tables, read back to the same results)."""

from __future__ import annotations

import gzip
import re

import numpy as np
import pandas as pd

from harness.report.views_csv import long_views, read_views, write_views
from harness.study import claims, findings
from tests.test_claims import SCENES, _study


def test_findings_group_the_claims_by_verdict_with_the_claims_numbers():
    df = _study(direction=-3.0)
    t = findings.table_findings(df, overhead={})
    c = claims.table_claims(df, overhead={})
    found = t.tidy
    assert list(found["key"]).count("t2-descriptors") == 1 and len(found) == c.tidy["key"].nunique()
    order = [findings.ORDER.index(v.split(" (")[0]) for v in found["verdict"]]
    assert order == sorted(order)  # grouped by verdict, in the documented order
    row = found.set_index("key").loc["t2-descriptors"]
    assert row["verdict"] == claims.DEPENDS
    assert row["paper-literal"].startswith("holds (") and row["paper-direction"].startswith("fails (")
    # every number printed is one of the claims table's (rounded), none typed by hand
    printed = {float(x) for text in found[["paper-literal", "paper-direction"]].to_numpy().ravel()
               for x in re.findall(r"[+-]\d+\.\d+", text)}
    known = set()
    for col in ("mean", "ci_low", "ci_high"):
        for digits in (2, 3):
            known |= {round(float(v), digits) for v in c.tidy[col].dropna()}
    assert printed and printed <= known
    assert t.caption.startswith(f"of {len(found)} claims: ") and "depends on the reading" in t.caption


def test_findings_through_harness_tables(tmp_path):
    from harness.cli import main
    from harness.report.results import write_results

    write_results(_study(), tmp_path)
    assert main(["tables", str(tmp_path), "--tables", "claims", "findings", "--plots"]) == 0
    md = (tmp_path / "tables" / "findings.md").read_text()
    assert "| t2-descriptors | holds (paper-literal only) |" in md
    assert (tmp_path / "views.csv.gz").is_file()


def test_views_round_trip_to_the_same_results_and_bytes(tmp_path):
    df = _study(scenes=SCENES[:2], lightgs_inf=("s1",))
    df.loc[df.index[:3], "status"] = "error"  # not measured: left out
    path = write_views(df, tmp_path)
    first = path.read_bytes()
    assert write_views(df, tmp_path).read_bytes() == first  # no time stamp: the same bytes
    text = gzip.decompress(first).decode()
    assert "\ninf\n" not in text and ",inf," in text  # identical images written as inf
    back = read_views(path)
    ok = df[df["status"] == "ok"].reset_index(drop=True)
    assert len(back) == len(ok) == len(long_views(df))
    key = ["scene", "method", "variant", "ratio", "view"]
    a = ok.sort_values(key, ignore_index=True)
    b = back.sort_values(key, ignore_index=True)
    for col in ("psnr", "ssim", "lpips"):
        np.testing.assert_array_equal(a[col].to_numpy(), b[col].to_numpy())  # full precision, inf kept
    pd.testing.assert_series_equal(a["params"], b["params"])
    ev_a, ev_b = claims.evaluations(a, {}), claims.evaluations(b, {})
    assert {k: v["paper-literal"].verdict for k, v in ev_a.items()} == \
        {k: v["paper-literal"].verdict for k, v in ev_b.items()}
