"""Tidy results: one row per (scene, frame, method, variant, ratio, view), written atomically.

Columns (see :data:`COLUMNS`): identification (``run, scene, label, kind, frame, method, variant,
params`` as canonical JSON, ``ratio``, ``keep = 1 - ratio``, ``view``), ``status`` (``ok``,
``skipped``, ``error``) with ``reason``, metrics (``psnr`` — +inf for identical images — ``ssim``,
``lpips``; the MPEG set ``rgb_psnr, yuv_psnr, yuv_ssim, …_om`` and ``occupancy`` % when measured), counts
(``splats_in``, ``splats_out``, and ``bytes``: the size of the pruned ``.ply`` the harness writes — the
rate of a rate point), the cut (``tau``: score value at the cut,
``tau_quantile = removed / N``), and stage timings in seconds (``score_s`` per (scene, method) —
repeated on each of its rows, ``prune_s``, ``render_ref_s`` per view, ``render_s``, ``metrics_s``).
Timings are those of the run that computed the entry (a cached rerun reports the original cost).

A skipped or failed (scene, method, ratio) has one row with ``view = ""`` and NaN metrics.
Files: ``results.parquet`` and ``results.csv``, each replaced atomically (temp + rename).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from harness.io.files import atomic_write_with
from harness.metrics.registry import METRICS as _METRICS

#: metrics beyond the 3DGS set (the MPEG families, :mod:`harness.metrics.registry`), then occupancy (%)
EXTRA_METRICS = [m.name for m in _METRICS if m.name not in ("psnr", "ssim", "lpips")] + ["occupancy"]
COLUMNS = [
    "run", "scene", "label", "kind", "frame", "method", "variant", "params", "ratio", "keep", "view",
    "status", "reason", "psnr", "ssim", "lpips", *EXTRA_METRICS, "splats_in", "splats_out", "bytes", "tau",
    "tau_quantile", "score_s", "prune_s", "render_ref_s", "render_s", "metrics_s", "renderer", "width", "height",
]
_TEXT = {"run", "scene", "label", "kind", "frame", "method", "variant", "params", "view", "status", "reason",
         "renderer"}
_INT = {"splats_in", "splats_out", "bytes", "width", "height"}


def to_frame(rows: list[dict]) -> pd.DataFrame:
    """Rows -> DataFrame with every column of :data:`COLUMNS` in order and stable dtypes."""
    df = pd.DataFrame(rows, columns=COLUMNS)
    for c in COLUMNS:
        if c in _TEXT:
            df[c] = df[c].astype(object).where(df[c].notna(), "").astype(str)
        elif c in _INT:
            df[c] = pd.to_numeric(df[c], errors="coerce").astype("Int64")
        else:
            df[c] = pd.to_numeric(df[c], errors="coerce").astype(np.float64)
    return df.sort_values(["scene", "frame", "method", "variant", "ratio", "view"], kind="stable",
                          ignore_index=True)


def write_results(df: pd.DataFrame, out_dir: str | Path) -> tuple[Path, Path]:
    """Write ``results.parquet`` and ``results.csv`` atomically; returns both paths."""
    out_dir = Path(out_dir)
    pq, csv = out_dir / "results.parquet", out_dir / "results.csv"
    atomic_write_with(pq, lambda p: df.to_parquet(p, index=False))
    atomic_write_with(csv, lambda p: df.to_csv(p, index=False))
    return pq, csv


def read_results(run_dir: str | Path) -> pd.DataFrame:
    """Stored results of a run directory (parquet, else csv)."""
    from harness.core.errors import InputError

    run_dir = Path(run_dir)
    pq, csv = run_dir / "results.parquet", run_dir / "results.csv"
    if pq.exists():
        return pd.read_parquet(pq)
    if csv.exists():
        return to_frame(pd.read_csv(csv, keep_default_na=False, na_values=[""]).to_dict("records"))
    raise InputError(run_dir, "no results.parquet or results.csv here (is it a `harness run` output folder?)")
