"""What a run writes once its stages are done, one sequence for every caller (``harness run``, and
any API that runs a study): tidy results, the figures' images, contact sheets, the run record, then
the tables, plots and report page through :func:`harness.report.outputs.publish` — the function
``harness tables`` and ``harness report`` end in too, so the three write the same files.

Everything is written into the run folder's staging folder and published as one step
(:mod:`harness.io.owned`): a reader, or a run killed half-way, never finds the results of one run
beside the tables of another. A run that measured nothing (every scene optional and absent, or
every stage failed) replaces nothing: the folder's earlier results, tables and page stay as they
were, and only its record is added under ``records/``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

from harness.report.outputs import PUBLISHED as PAGE_OUTPUTS


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


#: what a run publishes into its folder, as one step (:class:`harness.io.owned.OwnedFolder`); the
#: records of earlier runs are carried along, everything else is this run's alone
PUBLISHED = ("results.parquet", "results.csv", "images", "contact_sheets", "run.json", "records") + PAGE_OUTPUTS


def finish_run(folder, config, runner, result, *, workers: int, cache_root, argv) -> Finished:
    """Write everything a finished run shows (module docstring) into the staging folder of ``folder``
    (the run's :class:`harness.io.owned.OwnedFolder`) and publish it as one step; ``runner``: the
    :class:`harness.run.runner.Runner` that ran it (its items, cache and reference keys make the
    contact sheets)."""
    from harness.report.outputs import publish
    from harness.report.record import contact_sheets, copy_images, summary_lines, write_run_json
    from harness.report.results import to_frame, write_results

    df = to_frame(result.rows)
    # the earlier records, and the earlier tables, plots and memo: unchanged inputs keep them (memo)
    stage = folder.stage(carry=("records",) + PAGE_OUTPUTS)
    if not (df["status"] == "ok").any():
        record = write_run_json(stage, config, result, workers=workers, cache_root=cache_root, argv=argv,
                                latest=False)
        folder.publish(["records"])
        lines = summary_lines(result, df, {"run record": folder.final(record)})
        lines.append(f"nothing measured: the earlier results, tables and page in {folder.path} are left as they were")
        return Finished(df, lines, measured=False)
    write_results(df, stage)
    copy_images(result.images, stage)
    sheets = contact_sheets(runner.items, runner.cache, runner.ref_key, stage, config.protocol.background)
    run_json = write_run_json(stage, config, result, workers=workers, cache_root=cache_root, argv=argv)
    published = publish(stage, df, json.loads(run_json.read_text()), replace=True)
    folder.publish(PUBLISHED)
    out = folder.path
    coverage = "; ".join(f"{k} " + " ".join(f"{100 * c:.0f}%" for c in v) for k, v in sheets.items())
    paths = {"results": out / "results.parquet", "results (csv)": out / "results.csv", "tables": out / "tables",
             "plots": out / "plots", "images": out / "images",
             "contact sheets": f"{out / 'contact_sheets'} (coverage per view: {coverage})",
             "run record": out / "run.json", "report page": out / "report.html", "stage cache": cache_root}
    written = published.written
    return Finished(df, summary_lines(result, df, paths), written.warnings + written.missing, len(written.paths),
                    notes=written.notes)
