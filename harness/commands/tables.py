"""`harness tables RUN_DIR`: rebuild a run's tables and plots from its stored results (no recomputation)."""

from __future__ import annotations

import json
from pathlib import Path

NAME = "tables"
HELP = "regenerate the tables and plots of a `harness run` output folder from its stored results"


def add_arguments(parser) -> None:
    parser.add_argument("run_dir", help="output folder of `harness run` (holds results.parquet)")
    parser.add_argument("--tables", nargs="*", default=None, help="table names (default: those of run.json)")
    parser.add_argument("--plots", nargs="*", default=None, help="plot names (default: those of run.json)")


def run(args) -> int:
    from harness.core.errors import InputError
    from harness.report.outputs import write_outputs
    from harness.report.results import read_results
    from harness.run.config import PLOTS, TABLES

    run_dir = Path(args.run_dir)
    df = read_results(run_dir)
    meta = {}
    if (run_dir / "run.json").exists():
        try:
            meta = json.loads((run_dir / "run.json").read_text())
        except ValueError:
            raise InputError(run_dir / "run.json", "is not valid JSON") from None
    tables = args.tables if args.tables is not None else meta.get("tables", list(TABLES))
    plots = args.plots if args.plots is not None else meta.get("plots", list(PLOTS))
    for name in tables:
        if name not in TABLES:
            raise InputError("--tables", f"unknown table {name!r}; known: {', '.join(TABLES)}")
    for name in plots:
        if name not in PLOTS:
            raise InputError("--plots", f"unknown plot {name!r}; known: {', '.join(PLOTS)}")
    anchor = (meta.get("config") or {}).get("anchor") if isinstance(meta.get("config"), dict) else None
    written = write_outputs(run_dir, df, tables, plots, anchor)
    for p in written:
        print(p)
    return 0
