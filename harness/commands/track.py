"""`harness track RUN_DIR [--baseline FILE] [--history DIR] [--update-baseline]`: nightly tracking.

Summarises the run (:mod:`harness.report.tracking`), appends the summary as one JSON line to
``<history>/history.jsonl``, compares it with the baseline and prints every check. Exit status:
0 when nothing regressed, 1 when something did (each regression printed on its own ``REGRESSION``
line), 2 for bad input (no results in RUN_DIR, unreadable or missing baseline).

``--update-baseline`` writes the run's summary as the new baseline (keeping the old file's
tolerances) after the comparison, and exits 0: it is how the first baseline is made and how a
reviewed change of expected numbers is accepted. Without it a missing baseline is an error.
"""

from __future__ import annotations

from pathlib import Path

from harness.core.paths import results_dir

NAME = "track"
HELP = "summarise a run into results/history/ and compare it with the baseline (exit 1 on a regression)"


def add_arguments(parser) -> None:
    parser.add_argument("run_dir", help="a `harness run` output folder (results.parquet + run.json)")
    parser.add_argument("--baseline", default=None,
                        help="baseline JSON (default: results/history/baseline.json)")
    parser.add_argument("--history", default=None, help="history folder (default: results/history)")
    parser.add_argument("--update-baseline", action="store_true",
                        help="write this run's summary as the baseline (keeps its tolerances); exit 0")
    parser.add_argument("--no-history", action="store_true", help="compare only; do not append to the history")


def run(args) -> int:
    from harness.core.errors import InputError
    from harness.report import tracking

    history = Path(args.history) if args.history else results_dir() / "history"
    baseline_path = Path(args.baseline) if args.baseline else results_dir() / "history" / "baseline.json"
    df, meta = tracking.read_run(args.run_dir)
    if not baseline_path.exists() and not args.update_baseline:
        raise InputError(baseline_path, "no baseline here; create one from a trusted run with "
                                        "`harness track RUN_DIR --update-baseline`")
    summary = tracking.build_summary(df, meta)
    if summary["calibration_source"] == "track":
        print(f"calibration: run.json has no calibration_s; timed the calibration workload now: "
              f"{summary['calibration_s']:.3f} s")
    else:
        print(f"calibration: {summary['calibration_s']:.3f} s (from {summary['calibration_source']})")
    print(f"run {summary['run']} at commit {summary['commit'][:12]}: {len(summary['groups'])} groups, "
          f"{len(summary['stages'])} timed stages")
    if not args.no_history:
        print(f"history: appended to {tracking.append_history(history, summary)}")

    regressions = 0
    baseline = tracking.load_baseline(baseline_path) if baseline_path.exists() else None
    if baseline is not None:
        findings = tracking.compare(baseline, summary)
        for f in findings:
            tag = {"regression": "REGRESSION", "ok": "ok", "new": "new", "note": "note"}[f.kind]
            print(f"{tag:<10} {f.message}")
        regressions = sum(f.kind == "regression" for f in findings)
        checked = sum(f.kind in ("ok", "regression") for f in findings)
        print(f"track: {checked} checks against {baseline_path} "
              f"(baseline commit {baseline['summary'].get('commit', 'unknown')[:12]}), {regressions} regressions")
    if args.update_baseline:
        tol = baseline.get("tolerances") if baseline else None
        print(f"baseline: wrote {tracking.write_baseline(baseline_path, summary, tol)}")
        return 0
    return 1 if regressions else 0
