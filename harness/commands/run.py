"""`harness run CONFIG [--workers N] [--threads T] [--executor local|ray] [--address A] [--out DIR] [--force]
[--cache DIR|URL]`: the CTC-style evaluation.

Reads and validates the YAML config (:mod:`harness.run.config`) and resolves every scene before any
work (:func:`harness.run.sources.check_sources`): a misspelt scene, method or metric, or a required
scene whose files are absent, is one line (with "did you mean") and exit status 2, and nothing is
written; scenes marked ``optional: true`` whose files are absent are skipped with a message. Then
it runs the staged, cached plan (:mod:`harness.run.runner`), writes tidy results, contact sheets and
the run record (``run.json``, kept per run under ``records/``), and publishes the tables, plots and
``report.html`` (:func:`harness.report.outputs.publish`, the same function as `harness tables` and
`harness report`), printing a summary saying where everything is. A stage that fails on some scene
is recorded in the results and run.json and makes the exit status 1. A table or plot of the config
that these results cannot make is a ``warning:`` line of the summary naming what is missing (the
exit status stays 0: the measurements are complete). The run is :func:`harness.api.study.run_study`
(``harness.evaluate`` in Python returns its rows); this module prints its summary.

A run that measured nothing (every scene optional and absent, or every stage failed) replaces
nothing: the earlier results, tables and page of the folder stay as they were, and only its record
is added under ``records/``.
"""

from __future__ import annotations

import sys

NAME = "run"
HELP = "evaluate pruning methods on scenes per a YAML config (cached, resumable)"


def add_arguments(parser) -> None:
    parser.add_argument("config", help="run config (YAML), e.g. ctc_configs/default.yaml")
    parser.add_argument("--workers", type=int, default=None, help="process pool size (default: the config's)")
    parser.add_argument("--threads", type=int, default=None,
                        help="threads (CPUs) per worker (default: cores // workers; with Ray: the config's "
                             "executor.cpus_per_task, else the same)")
    parser.add_argument("--out", default=None, help="output folder (default: the config's `output`)")
    parser.add_argument("--force", action="store_true", help="recompute every stage, ignoring cached results")
    parser.add_argument(
        "--cache",
        default=None,
        help="stage cache folder or fsspec URL such as s3://bucket/prefix (default: <harness "
        "cache>/stages, shared by all runs); with Ray on several nodes, a location every node reaches",
    )
    parser.add_argument(
        "--executor",
        choices=("local", "ray"),
        default=None,
        help="where the work runs: local process pool (default) or Ray (default: the config's `executor`)",
    )
    parser.add_argument("--address", default=None,
                        help="Ray cluster to use: auto, HOST:PORT or ray://HOST:10001 (implies --executor ray; "
                             "without it Ray starts a local cluster of --workers workers on this machine)")


#: how this command names the API's arguments (:func:`harness.core.errors.naming`)
FLAGS = {"workers": "--workers", "threads": "--threads", "address": "--address", "executor": "--executor",
         "out": "--out", "cache": "--cache"}


def run(args) -> int:
    from harness.api.study import run_study
    from harness.core.errors import naming

    with naming(FLAGS):
        study = run_study(args.config, out=args.out, executor=args.executor, address=args.address,
                          workers=args.workers, threads=args.threads, cache=args.cache, force=args.force,
                          argv=sys.argv[1:])
    for line in study.summary:
        print(line)
    if study.measured:
        for line in study.warnings:  # what the config asked for and these results cannot show
            print(f"warning: {line}")
        for line in study.notes:  # tables of some protocols only: what the config measured there
            print(f"note: {line}")
        print(f"wrote {study.written} table/plot files")
    return 1 if study.errors else 0
