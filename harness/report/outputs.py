"""Everything a run folder shows, rebuilt from its stored results: tables, then plots."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from harness.report.plots import write_plots
from harness.report.tables import write_tables


def write_outputs(run_dir: str | Path, df: pd.DataFrame, tables, plots, anchor: str | None = None) -> list[Path]:
    """Tables and plots of a run folder from its results (no recomputation); ``anchor``: the bd table's."""
    return write_tables(df, run_dir, tables, anchor) + write_plots(df, run_dir, plots)
