"""`harness tables RUN_DIR`: rebuild a run's tables and plots from its stored results (no recomputation).

Prints the files written. A requested table or plot that these results cannot make (e.g. the
ablation when the ablation variants were not run at 20 %) is one line on stderr saying what is
missing; the others are still written, and the exit status is then 2 (as for any other input that
cannot give what was asked).
"""

from __future__ import annotations

import sys
from pathlib import Path

NAME = "tables"
HELP = "regenerate the tables and plots of a `harness run` output folder from its stored results"


def add_arguments(parser) -> None:
    parser.add_argument("run_dir", help="output folder of `harness run` (holds results.parquet)")
    parser.add_argument("--tables", nargs="*", default=None, help="table names (default: those of run.json)")
    parser.add_argument("--plots", nargs="*", default=None, help="plot names (default: those of run.json)")
    parser.add_argument("--reference", default=None,
                        help="method every other is compared with per view (comparison and versus tables; "
                             "default: random)")


def run(args) -> int:
    from harness.core.errors import InputError
    from harness.io.files import sweep_stale_temps
    from harness.report.outputs import write_outputs
    from harness.report.results import read_results
    from harness.run.config import PLOTS, TABLES

    run_dir = Path(args.run_dir)
    df = read_results(run_dir)
    sweep_stale_temps(run_dir, recursive=True)
    from harness.report.tracking import read_run_json

    meta = read_run_json(run_dir / "run.json") if (run_dir / "run.json").exists() else {}
    tables = args.tables if args.tables is not None else meta.get("tables", list(TABLES))
    plots = args.plots if args.plots is not None else meta.get("plots", list(PLOTS))
    for key, names in (("tables", tables), ("plots", plots)):
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise InputError(run_dir / "run.json", f"'{key}' must be a list of names, got {str(names)[:60]}")
    for name in tables:
        if name not in TABLES:
            raise InputError("--tables", f"unknown table {name!r}; known: {', '.join(TABLES)}")
    for name in plots:
        if name not in PLOTS:
            raise InputError("--plots", f"unknown plot {name!r}; known: {', '.join(PLOTS)}")
    anchor = (meta.get("config") or {}).get("anchor") if isinstance(meta.get("config"), dict) else None
    written = write_outputs(run_dir, df, tables, plots, reference=args.reference, anchor=anchor)
    for p in written.paths:
        print(p)
    for line in written.warnings:
        print(f"harness: warning: {line}", file=sys.stderr)
    for line in written.missing:
        print(f"harness: {line}", file=sys.stderr)
    return 2 if written.missing else 0
