"""``views.csv.gz``: a run's per-view measurements, one row per (scene, protocol, method, variant, ratio,
view), every metric it carries — small enough to commit beside a study's tables, so that any table
or verdict can be recomputed from the repository (``tests/test_claims_rederive.py`` does it for the
claims).

Columns: :data:`ID` (``params``: the variant's parameters as canonical JSON, as in the results;
``reading`` its ``reading`` parameter, empty for methods without one), then the measured metrics
(``psnr`` +inf for identical images, written ``inf``) in the results' column order. Only measured
rows (``status == ok``); no timings (they describe the machine, not the method). Floats are written
at full precision (Python's shortest round-trip form), so a value read back is the value measured.
The gzip stream carries no time stamp: the same results give the same bytes.
"""

from __future__ import annotations

import gzip
import io
import json
from pathlib import Path

import pandas as pd

from harness.io.files import atomic_write_bytes
from harness.report.results import columns, metric_columns, unpruned_gt_columns

NAME = "views.csv.gz"
ID = ["scene", "label", "kind", "protocol", "frame", "method", "variant", "reading", "params", "ratio", "keep", "view",
      "width", "height", "splats_in", "splats_out", "bytes"]


def _reading(params: str) -> str:
    try:
        return str(json.loads(params or "{}").get("reading", ""))
    except ValueError:
        return ""


def long_views(df: pd.DataFrame) -> pd.DataFrame:
    """The measured rows of ``df`` (results columns) as :data:`ID` + the metrics they carry."""
    ok = df[df["status"] == "ok"].copy()
    ok["reading"] = [_reading(p) for p in ok["params"]]
    metrics = [m for m in metric_columns() + unpruned_gt_columns() if m in ok and ok[m].notna().any()]
    out = ok[[c for c in ID if c in ok] + metrics]
    order = [c for c in ("scene", "protocol", "frame", "method", "variant", "ratio", "view") if c in out]
    return out.sort_values(order, kind="stable", ignore_index=True)


def write_views(df: pd.DataFrame, run_dir: str | Path) -> Path:
    """Write ``<run_dir>/views.csv.gz`` atomically (deterministic bytes); returns its path."""
    text = long_views(df).to_csv(index=False)
    buf = io.BytesIO()
    with gzip.GzipFile(filename="", mode="wb", fileobj=buf, mtime=0, compresslevel=9) as gz:
        gz.write(text.encode())
    path = Path(run_dir) / NAME
    atomic_write_bytes(path, buf.getvalue())
    return path


def read_views(path: str | Path) -> pd.DataFrame:
    """``views.csv.gz`` back as a results frame (:func:`harness.report.results.columns`, ``status`` ok,
    no timings): what the tables need to be rebuilt."""
    from harness.report.results import to_frame

    text = {"frame": str, "view": str, "variant": str, "reading": str, "params": str, "label": str, "kind": str}
    v = pd.read_csv(path, dtype=text)
    for c in text:
        if c in v:
            v[c] = v[c].fillna("")
    v["status"] = "ok"
    known = set(columns())
    return to_frame(v[[c for c in v.columns if c in known]].to_dict("records"))
