"""Everything a run folder shows, rebuilt from its stored results: tables, then plots."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from harness.report import catalog
from harness.report.plots import write_plots
from harness.report.tabledata import Written
from harness.report.tables import write_tables


def write_outputs(run_dir: str | Path, df: pd.DataFrame, tables, plots, **opts) -> Written:
    """Tables and plots of a run folder from its results (no recomputation); ``opts`` reach the
    table builders that take them (``reference=``). ``missing`` names what could not be made, and why."""
    with catalog.budget_notes(df):  # e.g. "ConfSplatPrune — lower bound (100 iterations)"
        return write_tables(df, run_dir, tables, **opts) + write_plots(df, run_dir, plots)
