"""The paper's tables from tidy results (pandas), as markdown, tidy csv and LaTeX.

Each builder returns a :class:`harness.report.tabledata.Table` — or a
:class:`~harness.report.tabledata.Missing` saying why it cannot be made from these results (which
variants or ratios are missing); ``write_tables`` writes ``tables/<name>.md`` (one small table per
group), ``.csv`` (long format, one header row) and ``.tex`` (the paper's wide layout) and reports the
missing ones (their stale files are removed). Only ``status == ok`` rows enter.

Which methods go where is asked of the pruner registry (:mod:`harness.report.catalog`): labels,
comparison groups, each method's cell of the paper's ablation grid; which metrics, of the metric
registry (every registered metric the results carry).

* ``comparison``, ``ablation``, ``versus``, ``per_scene``: cells with per-view paired differences and
  t intervals, :mod:`harness.report.cell_tables`.
* ``keep`` (Table 3) and ``sensitivity`` (presets, voxel sizes at keep 0.7): per scene and pooled,
  with paired intervals against the reference cell (:mod:`harness.report.sensitivity`).
* ``runtime``: scoring seconds per scene of every method's default variant, with the descriptor
  overhead betadesc − betadesc-nodesc in seconds and in % of betadesc-nodesc's time — "–" when that
  time is under :data:`MIN_BASE_S` (a percentage of timer noise means nothing).
* ``bd`` and ``ctc``: rate points, BD-rate / BD-PSNR against the config's anchor, and the CTC's
  per-sequence CSV layout (:mod:`harness.report.bd`).
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from harness.core.registry import Registry
from harness.io.files import atomic_write_text
from harness.report import bd, catalog, cell_tables, photos, sensitivity
from harness.report.summary import protocol_subsets, summarise
from harness.report.tabledata import Built, Missing, Table, Written, as_table
from harness.report.verdicts import Lead

#: the runtime table's overhead percentage needs at least this many seconds in its denominator
MIN_BASE_S = 1.0


def _fmt(v, digits: int) -> str:
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return "–"
    if np.isinf(v):
        return "inf"
    return f"{v:.{digits}f}"


# --------------------------------------------------------------------------- tables
def table_runtime(s: pd.DataFrame):
    """Scoring seconds per scene and method (the summary's ``score_s``: the mean over frames, with
    ``score_s_std`` over frames in the .csv)."""
    d = s[s["variant"] == "default"].drop_duplicates(["label", "method"])
    if d.empty:
        return Missing("no measured default variant")
    wide = d.pivot(index="label", columns="method", values="score_s")
    wide = wide[catalog.method_order(wide.columns)]
    tidy = d[["scene", "label", "method", "score_s", "score_s_std", "frames", "splats_in"]].copy()
    tidy.insert(3, "method_label", [catalog.method_label(m) for m in tidy["method"]])
    wide.insert(0, "splats", d.drop_duplicates("label").set_index("label")["splats_in"].reindex(wide.index))
    pair = catalog.descriptor_pair()
    notes = ["scoring seconds per scene (mean over frames), as measured by the run that computed them"]
    if pair is not None and pair[0] in wide and pair[1] in wide:
        without, full = pair
        wide["desc. overhead (s)"] = wide[full] - wide[without]
        wide["desc. overhead (%)"] = (100 * wide["desc. overhead (s)"] / wide[without]).where(
            wide[without] >= MIN_BASE_S
        )
        if wide["desc. overhead (%)"].isna().any():
            notes.append(f"desc. overhead (%): – where {catalog.method_label(without)} took under {MIN_BASE_S:g} s "
                         "(a percentage of so short a time says nothing); the seconds column still holds")
    wide.index.name = "scene"
    wide.columns = [catalog.method_label(c) + (" (s)" if c in d["method"].values else "") for c in wide.columns]
    disp = wide.copy().astype(object)
    for c in wide.columns:
        disp[c] = [str(int(v)) if c == "splats" and np.isfinite(v) else _fmt(v, 1 if "%" in c else 2) for v in wide[c]]
    frames = d["frames"].astype(int)
    n = f"{frames.min()}" if frames.min() == frames.max() else f"{frames.min()}–{frames.max()}"
    return Table(disp, notes, tidy.reset_index(drop=True),
                 caption=f"n = {n} frame(s) per scene, one scoring run each (the time of the run that computed it); "
                         "no interval")


@dataclass(frozen=True)
class TableSpec:
    """A table a config or ``harness tables`` can name: ``build(data, **options) -> Table | Missing``
    (``data``: the per-view results, or with ``reads="summary"`` one row per cell, :func:`summarise`;
    options it names, such as ``reference=`` or ``anchor=``, are passed), its ``title``, and
    ``with_photos``: it belongs to the held-out view protocols whose views have photos (when any has).
    A table that judges things gives the report page ``verdicts`` (a cell's words -> its status, so
    the page colours verdicts, not signs) and may ``lead`` it (:mod:`harness.report.verdicts`)."""

    name: str
    build: Callable
    title: str
    reads: str = "results"
    with_photos: bool = False
    verdicts: Callable | None = None
    lead: Lead | None = None


#: every table, in registration order (built-ins below; third-party ones through the ``harness.tables``
#: entry-point group: a module whose import calls :func:`register_table`)
TABLE_SPECS: Registry[TableSpec] = Registry("table", modules=(__name__,), group="harness.tables")


def register_table(name: str, *, build: Callable, title: str, reads: str = "results", with_photos: bool = False,
                   verdicts: Callable | None = None, lead: Lead | None = None) -> TableSpec:
    """Register table ``name`` (:class:`TableSpec`); ``lead`` needs ``verdicts``."""
    if reads not in ("results", "summary"):
        raise ValueError(f"table {name!r}: reads must be 'results' or 'summary', got {reads!r}")
    if lead is not None and (verdicts is None or not isinstance(lead, Lead)):
        raise ValueError(f"table {name!r}: lead must be a harness.report.verdicts.Lead, with verdicts= given")
    spec = TableSpec(name, build, title, reads, with_photos, verdicts, lead)
    TABLE_SPECS.add(name, spec, same=lambda a, b: (a.title, a.build.__qualname__) == (b.title, b.build.__qualname__))
    return spec


register_table("comparison", build=cell_tables.table_comparison,
               title="Comparison at low (10 %), mid (20 %) and high (30 %) pruning (paper Table 1)")
register_table(
    "ablation", build=cell_tables.table_ablation, title="Ablation: descriptors × Beta at 20 % pruning (paper Table 2)"
)
register_table("keep", build=sensitivity.table_keep,
               title="Keep fractions 0.7 / 0.5 / 0.3 with and without descriptors (paper Table 3)")
register_table("sensitivity", build=sensitivity.table_sensitivity,
               title="Sensitivity: coefficient presets and voxel sizes at keep 0.7")
register_table("runtime", build=table_runtime, title="Scoring runtime per scene", reads="summary")
register_table("per_scene", build=cell_tables.table_per_scene, title="Per-scene descriptor gains")
register_table("versus", build=cell_tables.table_versus, title="Every method against the reference, per view")
register_table("bd", build=bd.table_bd, reads="summary",
               title="Bjøntegaard deltas against the anchor (BD-rate on .ply bytes; RGB-PSNR, YUV-PSNR, YUV-SSIM)")
register_table("ctc", build=bd.table_ctc, title="Per sequence and rate point (MPEG CTC layout)", reads="summary")
register_table("photos", build=photos.table_photos, with_photos=True,
               title="Against the captured photos: pruned and unpruned renders, per held-out view")


def _call(fn, data, opts: dict):
    """``fn(data, **the opts its signature names)`` (options such as ``reference=``)."""
    params = inspect.signature(fn).parameters
    return fn(data, **{k: v for k, v in opts.items() if k in params and v is not None})


def build_tables(df: pd.DataFrame, names, **opts) -> dict[str, Table | Missing]:
    """Each named table built from the results (a :class:`Missing` where it cannot be)."""
    s = summarise(df)
    specs = {name: TABLE_SPECS.get(name) for name in names}
    return {name: as_table(_call(t.build, s if t.reads == "summary" else df, opts)) for name, t in specs.items()}


def __getattr__(name: str):
    """``TABLES``: the tables a config or ``harness tables --tables`` can name, built-ins and plugins'
    (looked up when first imported, once this module is whole: a plugin's tables are then its own)."""
    if name == "TABLES":
        return tuple(TABLE_SPECS.names())
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def base_title(name: str) -> str:
    """A table's registered title (its name when it is not registered)."""
    return TABLE_SPECS.get(name).title if name in TABLE_SPECS else name


def title(name: str, protocol: str) -> str:
    """A table's title, with the held-out view protocol its rows come from (every protocol, the
    primary one too; none only for results that carry no protocol)."""
    from harness.views.protocols import notes

    base = base_title(name)
    return base + (f" — held-out views: {protocol} ({notes(protocol)})" if protocol else "")


def with_caption(t: Table | Missing) -> Table | Missing:
    """``t`` with a caption: its own, else one read from its tidy rows — ``n`` per cell where they
    carry it, and the interval method where they carry intervals (every table's caption says both)."""
    if isinstance(t, Missing) or t.caption:
        return t
    from harness.report import stats

    parts = []
    if "n" in t.tidy and t.tidy["n"].notna().any():
        lo, hi = int(t.tidy["n"].min()), int(t.tidy["n"].max())
        parts.append(f"n = {lo if lo == hi else f'{lo}–{hi}'} per cell")
    parts.append(f"intervals: {stats.INTERVAL_DESCRIPTION}" if {"ci_low", "ci_high"} <= set(t.tidy)
                 else "no interval")
    return dataclasses.replace(t, caption="; ".join(parts))


def _belongs(name: str, proto: str, with_photos: set[str]) -> bool:
    """A table of the photos belongs to the protocols whose views have photos (when any has)."""
    return not TABLE_SPECS.get(name).with_photos or not with_photos or proto in with_photos


def _remove_stale(out_dir: Path, key: str) -> str:
    """Remove the files an earlier build wrote for table ``key``; `` (removed its earlier ...)`` or ``""``."""
    stale = [f for ext in ("md", "csv", "tex") if (f := out_dir / f"{key}.{ext}").exists()]
    for f in stale:
        f.unlink()
    return f" (removed its earlier {', '.join(f.name for f in stale)})" if stale else ""


def _write_table(out_dir: Path, b: Built) -> list[Path]:
    """``<key>.md``, ``.csv`` (its tidy rows, with their protocol) and ``.tex`` of one built table."""
    from harness.report.formats import to_latex, to_markdown

    t = b.table
    paths = []
    for ext, text in (("md", to_markdown(t, b.title)), ("csv", t.tidy.assign(protocol=b.protocol).to_csv(index=False)),
                      ("tex", to_latex(t.disp, b.title, [t.caption, *t.notes], label=f"table:{b.key}"))):
        path = out_dir / f"{b.key}.{ext}"
        atomic_write_text(path, text)
        paths.append(path)
    return paths


def _sort_absent(out: Written, absent: list[tuple[str, str, str]]) -> None:
    """A table made for none of the protocols is missing; one made for some is a note for the others."""
    made = {b.name for b in out.built.values() if not isinstance(b.table, Missing)}
    for name, proto, line in absent:
        if name in made:
            out.notes.append(line.replace(" not written: ", f" not made for the {proto} views: ", 1))
        else:
            out.missing.append(line)


def write_tables(df: pd.DataFrame, out_dir: str | Path, names, **opts) -> Written:
    """Write ``tables/<name>.md|csv|tex`` for each table that can be made, plus ``tables/summary.csv``,
    per held-out view protocol (:func:`harness.report.summary.protocol_subsets`): the primary
    (training rig) one as ``<name>.*``, the others as ``<name>-<protocol>.*``; every title, caption
    and tidy row names its protocol. Tables these results cannot make are listed in ``missing``;
    their files from an earlier build are removed, since they describe other results than the
    ``results.parquet`` beside them (``missing`` says so)."""
    out_dir = Path(out_dir) / "tables"
    out_dir.mkdir(parents=True, exist_ok=True)
    subsets = protocol_subsets(df)
    with_photos = {proto for proto, _, sub in subsets if photos.has_photos(sub)}
    summaries = [summarise(sub).assign(protocol=proto) for proto, _, sub in subsets]
    out = Written([out_dir / "summary.csv"])
    atomic_write_text(out.paths[0], pd.concat(summaries, ignore_index=True).to_csv(index=False))
    absent = []  # (table, protocol, line): missing, or a note when the table was made for another protocol
    for proto, suffix, sub in subsets:
        here = [n for n in names if _belongs(n, proto, with_photos)]
        for name, t in build_tables(sub, here, **opts).items():
            b = out.built[name + suffix] = Built(name + suffix, name, proto, title(name, proto), with_caption(t))
            if isinstance(b.table, Missing):
                absent.append((name, proto, f"table {b.key} not written: {b.table.reason}"
                               + _remove_stale(out_dir, b.key)))
                continue
            out.warnings += b.table.warnings
            out.paths += _write_table(out_dir, b)
    _sort_absent(out, absent)
    return out
