"""`harness tables RUN_DIR`: rebuild a run's tables, plots and report page from its stored results
(no recomputation), through the same function as `harness run` and `harness report`
(:func:`harness.report.outputs.publish`).

Prints the files written. A requested table or plot that these results cannot make (e.g. the
ablation when the ablation variants were not run at 20 %) is one line on stderr saying what is
missing; the others are still written, and the exit status is then 2 (as for any other input that
cannot give what was asked). With only ``--tables`` (or only ``--plots``) given, the run's own plots
(tables) that cannot be made are warnings: they were not asked for.
"""

from __future__ import annotations

import sys
from pathlib import Path

NAME = "tables"
HELP = "regenerate the tables, plots and report page of a `harness run` output folder from its stored results"


def add_arguments(parser) -> None:
    parser.add_argument("run_dir", help="output folder of `harness run` (holds results.parquet)")
    parser.add_argument("--tables", nargs="*", default=None, help="table names (default: those of run.json)")
    parser.add_argument("--plots", nargs="*", default=None, help="plot names (default: those of run.json)")
    parser.add_argument("--reference", default=None,
                        help="method every other is compared with per view (comparison and versus tables; "
                             "default: random)")


def run(args) -> int:
    from harness.io.owned import OwnedFolder
    from harness.report.tracking import read_run

    run_dir = Path(args.run_dir)
    with OwnedFolder(run_dir, f"harness tables {run_dir}", create=False) as folder:  # refused while a run writes it
        return _rebuild(args, folder, *read_run(run_dir))


def _rebuild(args, folder, df, meta) -> int:
    from harness.core.errors import InputError
    from harness.core.suggest import unknown
    from harness.io.files import sweep_stale_temps
    from harness.report.outputs import PUBLISHED, READS, chosen, publish
    from harness.report.plots import PLOTS
    from harness.report.tables import TABLES

    run_dir = folder.path
    sweep_stale_temps(run_dir, recursive=True)
    tables, plots, _ = chosen(meta)
    tables = args.tables if args.tables is not None else tables
    plots = args.plots if args.plots is not None else plots
    for key, names in (("tables", tables), ("plots", plots)):
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise InputError(run_dir / "run.json", f"'{key}' must be a list of names, got {str(names)[:60]}")
    for flag, names, known in (("--tables", tables, TABLES), ("--plots", plots, PLOTS)):
        for name in names:
            if name not in known:
                raise InputError(flag, unknown(flag.removeprefix("--")[:-1], name, known))
    stage = folder.stage(carry=READS + PUBLISHED)  # what the page reads, and the tables and plots not rebuilt
    written = publish(stage, df, meta, tables=tables, plots=plots, reference=args.reference).written
    folder.publish(PUBLISHED)
    for p in written.paths:
        print(folder.final(p))
    print(run_dir / "report.html")
    for line in written.warnings:
        print(f"harness: warning: {line}", file=sys.stderr)
    for line in written.notes:  # made for other protocols: these results hold none of its variants here
        print(f"harness: note: {line}", file=sys.stderr)
    # what the command line named explicitly and could not be made fails the command; the run's
    # own defaults for the other kind (plots when only --tables was given, and so on) only warn
    asked = {
        "table": args.tables is not None or args.plots is None,
        "plot": args.plots is not None or args.tables is None,
    }
    failed = False
    for line in written.missing:
        kind = line.split(" ", 1)[0]
        if asked.get(kind, True):
            failed = True
            print(f"harness: {line}", file=sys.stderr)
        else:
            print(f"harness: warning: {line}", file=sys.stderr)
    return 2 if failed else 0
