"""`harness track RUN_DIR [--baseline FILE] [--history DIR] [--update-baseline]`: nightly tracking.

Summarises the run (:mod:`harness.report.tracking`), compares it with the baseline and prints every
check. Everything is decided before anything is written: the run and the baseline are read and
checked, and the baseline must be of the same config and held-out view protocols as the run
(another is one line and exit status 2 — a ci run compared with the nightly baseline is not 74
regressions). Only then, and only when asked, files are written:

* ``--history DIR`` appends the summary as one JSON line to ``DIR/history.jsonl`` (the nightly
  workflow passes ``--history results/history``; without the flag nothing is appended, so trying
  `harness track` on a run never touches the tracked history);
* ``--update-baseline`` writes the run's summary as the baseline (keeping the old file's tolerances)
  and exits 0: how the first baseline is made and how a reviewed change of expected numbers is
  accepted. Without it a missing baseline is an error.

Exit status: 0 when nothing regressed, 1 when something did (each regression printed on its own
``REGRESSION`` line), 2 for bad input (no results in RUN_DIR, an unreadable, missing or unlike
baseline, a history that is not a regular file).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from harness.core.paths import results_dir

NAME = "track"
HELP = "compare a run with the baseline of its config (exit 1 on a regression); --history DIR appends to a history"


def add_arguments(parser) -> None:
    parser.add_argument("run_dir", help="a `harness run` output folder (results.parquet + run.json)")
    parser.add_argument("--baseline", default=None,
                        help="baseline JSON of the run's config (default: results/history/baseline.json, the "
                             "nightly config's)")
    parser.add_argument("--history", default=None, metavar="DIR",
                        help="append the run's summary to DIR/history.jsonl (the nightly job: --history "
                             "results/history); default: append nothing")
    parser.add_argument("--update-baseline", action="store_true",
                        help="write this run's summary as the baseline (keeps its tolerances); exit 0")
    parser.add_argument("--no-history", action="store_true", help=argparse.SUPPRESS)  # the default now


def run(args) -> int:
    from harness.core.errors import InputError
    from harness.io.owned import reading
    from harness.report import tracking

    baseline_path = Path(args.baseline) if args.baseline else results_dir() / "history" / "baseline.json"
    with reading(args.run_dir):  # not while a run writes it
        df, meta = tracking.read_run(args.run_dir)
    baseline = tracking.load_baseline(baseline_path) if baseline_path.exists() else None
    if baseline is None and not args.update_baseline:
        raise InputError(baseline_path, "no baseline here; create one from a trusted run with "
                                        "`harness track RUN_DIR --update-baseline`")
    summary = tracking.build_summary(df, meta)
    if baseline is not None:
        tracking.check_like(baseline, summary, baseline_path, args.run_dir)
    findings = tracking.compare(baseline, summary) if baseline is not None else []
    # decided: from here on only output
    if summary["calibration_source"] == "track":
        print(f"calibration: run.json has no calibration_s; timed the calibration workload now: "
              f"{summary['calibration_s']:.3f} s")
    else:
        print(f"calibration: {summary['calibration_s']:.3f} s (from {summary['calibration_source']})")
    print(f"run {summary['run']} (held-out views: {', '.join(summary['protocols']) or 'unnamed'}) at commit "
          f"{summary['commit'][:12]}: {len(summary['groups'])} groups, {len(summary['stages'])} timed stages")
    for f in findings:
        tag = {"regression": "REGRESSION", "ok": "ok", "new": "new", "note": "note"}[f.kind]
        print(f"{tag:<10} {f.message}")
    regressions = sum(f.kind == "regression" for f in findings)
    if baseline is not None:
        checked = sum(f.kind in ("ok", "regression") for f in findings)
        print(f"track: {checked} checks against {baseline_path} "
              f"(baseline commit {baseline['summary'].get('commit', 'unknown')[:12]}), {regressions} regressions")
    if args.history:
        print(f"history: appended to {tracking.append_history(args.history, summary)}")
    else:
        print("history: not written (--history DIR appends this summary)")
    if args.update_baseline:
        tol = baseline.get("tolerances") if baseline else None
        print(f"baseline: wrote {tracking.write_baseline(baseline_path, summary, tol)}")
        return 0
    return 1 if regressions else 0
