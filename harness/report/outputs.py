"""One path from a run's stored results to everything it shows: tables, plots, then the report page.

``harness run`` (once its results and run record are written), ``harness tables`` and ``harness
report`` all end in :func:`publish`, so the three write the same ``tables/``, ``plots/``,
``views.csv.gz`` (the per-view measurements, :mod:`harness.report.views_csv`) and ``report.html``
from the same results: the page is drawn from the tables just written (per
held-out view protocol, each labelled with it), never rebuilt another way.

Which tables and plots: the run record's (``run.json``: the config's ``tables``/``plots``), else
all; ``harness tables --tables/--plots`` narrows them. The BD anchor is the record's (``anchor``,
else the config's, else :data:`harness.report.bd.DEFAULT_ANCHOR`); ``reference`` is the method
every cell table compares with (default ``random``).

Tables and plots are rebuilt only when the results, these choices or the code that makes them
changed (:mod:`harness.report.memo`); the page is always redrawn (it shows every run record).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from harness.report import catalog
from harness.report.plots import PLOTS, write_plots
from harness.report.tabledata import Written
from harness.report.tables import TABLES, write_tables
from harness.report.views_csv import write_views

#: what :func:`publish` writes into a run folder, and what it reads there besides the results (the
#: page's renders and run records): the entries a command that rebuilds them stages and publishes
#: (:class:`harness.io.owned.OwnedFolder`)
#: what a publication owns in a run folder; the memo (``.outputs``, :mod:`harness.report.memo`) with the
#: tables and plots it keeps, so a cached rerun that stages them finds them
PUBLISHED = ("tables", "plots", "views.csv.gz", "report.html", ".outputs")
READS = ("images", "records")


@dataclass
class Published:
    """What :func:`publish` wrote: the tables and plots (``written``) and the page."""

    written: Written
    page: Path


def chosen(meta: dict) -> tuple[list[str], list[str], str | None]:
    """(tables, plots, BD anchor) a run record asks for; a record that names none: every table and
    plot (an empty list asks for none: ``plots: []`` draws nothing)."""
    config = meta.get("config") if isinstance(meta.get("config"), dict) else {}
    anchor = meta.get("anchor") or config.get("anchor")
    return _names(meta.get("tables"), TABLES), _names(meta.get("plots"), PLOTS), \
        anchor if isinstance(anchor, str) else None


def _names(value, every) -> list:
    """A record's list of names (None: ``every``); anything else is handed on for the caller to refuse."""
    return list(every) if value is None else list(value) if isinstance(value, (list, tuple)) else value


def publish(run_dir: str | Path, df: pd.DataFrame, meta: dict, *, tables=None, plots=None,
            reference: str | None = None, replace: bool = False) -> Published:
    """Write a run folder's tables, plots and ``report.html`` from its results and run record.
    ``replace``: when the memo does not hold them, the folder's earlier tables and plots go first (a
    run's outputs are exactly what its config names; ``harness tables`` keeps those it does not rebuild)."""
    from harness.report import memo
    from harness.report.page import write_report

    run_dir = Path(run_dir)
    names, plot_names, anchor = chosen(meta)
    tables = names if tables is None else list(tables)
    plots = plot_names if plots is None else list(plots)
    digest = memo.inputs_digest(df, {"tables": tables, "plots": plots, "reference": reference, "anchor": anchor})
    kept = memo.load(run_dir, digest)
    with catalog.budget_notes(df):  # e.g. "ConfSplatPrune — lower bound (100 iterations)"
        if kept is not None:
            written, drawn = kept
        else:
            memo.forget(run_dir)
            if replace:  # emptied, not removed: an entry absent from a staging folder is left as it was
                for sub in ("tables", "plots"):
                    shutil.rmtree(run_dir / sub, ignore_errors=True)
                    (run_dir / sub).mkdir()
            drawn = write_plots(df, run_dir, plots)
            written = write_tables(df, run_dir, tables, reference=reference, anchor=anchor) + drawn
            written.paths.append(write_views(df, run_dir))
            memo.save(run_dir, digest, written, drawn)
        page = write_report(run_dir, df, meta, written.built, written.missing, plots=drawn.paths)
    return Published(written, page)
