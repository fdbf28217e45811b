"""`harness report RUN_DIR`: write ``RUN_DIR/report.html``, one self-contained page of a run.

The page (:mod:`harness.report.page`) holds the run's tables with their confidence intervals, the
curves and figures of ``RUN_DIR/plots``, an image comparison (slider + amplified difference) per
scene × method × ratio from ``RUN_DIR/images``, and the run record. It needs no network and no file
beside it. `harness run` writes it at the end of every run; this command rebuilds it from the stored
results (no recomputation).
"""

from __future__ import annotations

NAME = "report"
HELP = "write RUN_DIR/report.html: tables with CIs, curves, image comparisons and the run record in one page"


def add_arguments(parser) -> None:
    parser.add_argument("run_dir", help="output folder of `harness run` (holds results.parquet)")
    parser.add_argument("--reference", default=None,
                        help="method every other is compared with per view (default: random)")


def run(args) -> int:
    from harness.report.page import write_report
    from harness.report.tracking import read_run

    df, meta = read_run(args.run_dir)
    print(write_report(args.run_dir, df, meta, reference=args.reference))
    return 0
