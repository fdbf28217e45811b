"""What a run writes once its stages are done, one sequence for every caller (``harness run``, and
any API that runs a study): tidy results, the figures' images, contact sheets, the run record, then
the tables, plots and report page through :func:`harness.report.outputs.publish` — the function
``harness tables`` and ``harness report`` end in too, so the three write the same files.

A run that measured nothing (every scene optional and absent, or every stage failed) replaces
nothing: the folder's earlier results, tables and page stay as they were, and only its record is
added under ``records/``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class Finished:
    """What :func:`finish_run` wrote: the tidy rows (``frame``), the summary lines to print, the
    tables' warnings (what the config asked for and these results cannot show), how many table and
    plot files were written, whether anything was measured, and the tables' notes (made for some
    held-out view protocols only: :class:`harness.report.tabledata.Written`)."""

    frame: object
    summary: list[str]
    warnings: list[str] = field(default_factory=list)
    written: int = 0
    measured: bool = True
    notes: list[str] = field(default_factory=list)


def finish_run(out_dir: Path, config, runner, result, *, workers: int, cache_root, argv) -> Finished:
    """Write everything a finished run shows (module docstring); ``runner``: the
    :class:`harness.run.runner.Runner` that ran it (its items, cache and reference keys make the
    contact sheets)."""
    from harness.report.outputs import publish
    from harness.report.record import contact_sheets, copy_images, summary_lines, write_run_json
    from harness.report.results import to_frame, write_results

    df = to_frame(result.rows)
    if not (df["status"] == "ok").any():
        record = write_run_json(out_dir, config, result, workers=workers, cache_root=cache_root, argv=argv,
                                latest=False)
        lines = summary_lines(result, df, {"run record": record})
        lines.append(f"nothing measured: the earlier results, tables and page in {out_dir} are left as they were")
        return Finished(df, lines, measured=False)
    pq, csv = write_results(df, out_dir)
    images = copy_images(result.images, out_dir)
    sheets = contact_sheets(runner.items, runner.cache, runner.ref_key, out_dir, config.protocol.background)
    run_json = write_run_json(out_dir, config, result, workers=workers, cache_root=cache_root, argv=argv)
    published = publish(out_dir, df, json.loads(run_json.read_text()))
    coverage = "; ".join(f"{k} " + " ".join(f"{100 * c:.0f}%" for c in v) for k, v in sheets.items())
    paths = {"results": pq, "results (csv)": csv, "tables": out_dir / "tables", "plots": out_dir / "plots",
             "images": images, "contact sheets": f"{out_dir / 'contact_sheets'} (coverage per view: {coverage})",
             "run record": run_json, "report page": published.page, "stage cache": cache_root}
    written = published.written
    return Finished(df, summary_lines(result, df, paths), written.warnings + written.missing, len(written.paths),
                    notes=written.notes)
