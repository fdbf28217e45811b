"""`harness report RUN_DIR`: rebuild a run folder's tables, plots and ``RUN_DIR/report.html``.

The page (:mod:`harness.report.page`) holds the run's tables with their confidence intervals, the
curves and figures, an image comparison (slider + amplified difference) per scene × method × ratio
from ``RUN_DIR/images``, and the records of every run into the folder. It needs no network and no
file beside it. `harness run` writes it at the end of every run, `harness tables` and this command
rebuild it from the stored results (no recomputation) through the same function
(:func:`harness.report.outputs.publish`), so all three write the same tables and the same page.
"""

from __future__ import annotations

NAME = "report"
HELP = "rebuild RUN_DIR's tables and report.html: tables with CIs, curves, image comparisons, run records"


def add_arguments(parser) -> None:
    parser.add_argument("run_dir", help="output folder of `harness run` (holds results.parquet)")
    parser.add_argument("--reference", default=None,
                        help="method every other is compared with per view (default: random)")


def run(args) -> int:
    import sys

    from harness.io.files import sweep_stale_temps
    from harness.io.owned import OwnedFolder
    from harness.report.outputs import PUBLISHED, READS, publish
    from harness.report.tracking import read_run

    # refused while a run writes the folder
    with OwnedFolder(args.run_dir, f"harness report {args.run_dir}", create=False) as folder:
        df, meta = read_run(args.run_dir)
        sweep_stale_temps(args.run_dir, recursive=True)
        stage = folder.stage(carry=READS + PUBLISHED)
        published = publish(stage, df, meta, reference=args.reference)
        folder.publish(PUBLISHED)
    for line in published.written.warnings + published.written.missing:
        print(f"harness: warning: {line}", file=sys.stderr)
    for line in published.written.notes:  # tables of some protocols only (as `run` and `tables` say)
        print(f"harness: note: {line}", file=sys.stderr)
    print(folder.final(published.page))
    return 0
