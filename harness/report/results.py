"""Tidy results: one row per (scene, frame, method, variant, ratio, view), written atomically.

Columns (see :func:`columns`): identification (``run, scene, label, kind, frame, method, variant,
params`` as canonical JSON, ``ratio``, ``keep = 1 - ratio``, ``protocol`` — the held-out view
protocol, :mod:`harness.views.protocols`: ``rig`` or e.g. ``shifted`` — ``view``), ``status`` (``ok``,
``skipped``, ``error``) with ``reason``, one column per registered metric (:func:`metric_columns`:
``psnr`` — +inf for identical images — ``ssim``, ``lpips``; the MPEG set ``rgb_psnr, yuv_psnr,
yuv_ssim, …_om``, the ``gt_`` twins, plugins' metrics; ``occupancy`` % when measured), counts
(``splats_in``, ``splats_out``, and ``bytes``: the size of the pruned ``.ply`` the harness writes — the
rate of a rate point), the cut (``tau``: score value at the cut,
``tau_quantile = removed / N``), and stage timings in seconds (``score_s`` per (scene, method) —
repeated on each of its rows, ``prune_s``, ``render_ref_s`` per view, ``render_s``, ``metrics_s``).
Timings are those of the run that computed the entry (a cached rerun reports the original cost).

A skipped or failed (scene, method, ratio) has one row with ``view = ""`` and NaN metrics.
Files: ``results.parquet`` and ``results.csv``, each replaced atomically (temp + rename).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from harness.io.files import atomic_write_with
from harness.metrics import registry

#: identification and status columns, before the metrics
ID_COLUMNS = ["run", "scene", "label", "kind", "frame", "method", "variant", "params", "ratio", "keep", "protocol",
              "view", "status", "reason"]
#: counts, the cut and the timings, after the metrics
TAIL_COLUMNS = ["splats_in", "splats_out", "bytes", "tau", "tau_quantile", "score_s", "prune_s", "render_ref_s",
                "render_s", "metrics_s", "renderer", "width", "height"]


def metric_columns() -> list[str]:
    """The registered metrics as result columns: the headline family first (``psnr, ssim, lpips``),
    then every other in registration order (the MPEG families, the ``gt_`` twins, plugins'), then
    ``occupancy`` (%)."""
    head = list(registry.headline())
    return head + [m.name for m in registry.METRICS if m.name not in head] + ["occupancy"]


def unpruned_gt_columns() -> list[str]:
    """On a view with a photo: the unpruned render's photo metrics (``gt_`` names) and the share of
    the frame its splats occupy (%), repeated on every row of the view (the pruned render's are ``gt_*``)."""
    return [f"unpruned_{m.name}" for m in registry.METRICS if registry.is_gt(m.name)] + ["unpruned_gt_occupancy"]


def columns() -> list[str]:
    """Every column of the tidy results, in order (module docstring)."""
    return ID_COLUMNS + metric_columns() + unpruned_gt_columns() + TAIL_COLUMNS


_TEXT = {"run", "scene", "label", "kind", "frame", "method", "variant", "params", "protocol", "view", "status",
         "reason", "renderer"}
_INT = {"splats_in", "splats_out", "bytes", "width", "height"}


def to_frame(rows: list[dict]) -> pd.DataFrame:
    """Rows -> DataFrame with every column of :func:`columns` in order and stable dtypes."""
    cols = columns()
    df = pd.DataFrame(rows, columns=cols)
    for c in cols:
        if c in _TEXT:
            df[c] = df[c].astype(object).where(df[c].notna(), "").astype(str)
        elif c in _INT:
            df[c] = pd.to_numeric(df[c], errors="coerce").astype("Int64")
        else:
            df[c] = pd.to_numeric(df[c], errors="coerce").astype(np.float64)
    return df.sort_values(["scene", "frame", "method", "variant", "ratio", "protocol", "view"], kind="stable",
                          ignore_index=True)


def write_results(df: pd.DataFrame, out_dir: str | Path) -> tuple[Path, Path]:
    """Write ``results.parquet`` and ``results.csv`` atomically; returns both paths."""
    from harness.core.errors import InputError

    out_dir = Path(out_dir)
    pq, csv = out_dir / "results.parquet", out_dir / "results.csv"
    for path, write in ((pq, lambda p: df.to_parquet(p, index=False)), (csv, lambda p: df.to_csv(p, index=False))):
        try:
            atomic_write_with(path, write)
        except OSError as err:  # pyarrow's errors name no file: say which one could not be written
            raise InputError(path, f"cannot write: {err.strerror or str(err).splitlines()[0]}") from None
    return pq, csv


#: columns every stored result must have (identification and status)
REQUIRED = ("scene", "method", "variant", "ratio", "status")


def _numeric() -> list[str]:
    """The columns that must hold numbers: ratios, every registered metric, counts and timings."""
    return ["ratio", "keep", *metric_columns(), *(c for c in TAIL_COLUMNS if c != "renderer")]


def read_results(run_dir: str | Path) -> pd.DataFrame:
    """Stored results of a run directory (parquet, else csv), checked: a readable regular file of
    bounded size, the :data:`REQUIRED` columns present, numeric columns numeric (a PSNR stored as
    text is an error, not a crash later)."""
    from harness.core.errors import InputError

    df, source = _read_table(Path(run_dir))
    missing = [c for c in REQUIRED if c not in df.columns]
    if missing:
        raise InputError(source, f"results lack the column(s) {', '.join(missing)}")
    for c in _numeric():
        if c in df.columns and not (pd.api.types.is_numeric_dtype(df[c]) or df[c].isna().all()):
            bad = next((v for v in df[c] if not isinstance(v, (int, float, np.number)) and v is not None), None)
            raise InputError(source, f"column {c!r} holds non-numbers (e.g. {str(bad)[:40]!r})")
    return df


def _read_table(run_dir: Path) -> tuple[pd.DataFrame, Path]:
    """(the stored results, the file they came from): ``results.parquet``, else ``results.csv``."""
    from harness.core.errors import InputError
    from harness.io.safe import check_regular

    pq, csv = run_dir / "results.parquet", run_dir / "results.csv"
    if pq.exists():
        check_regular(pq, "results", "results file")
        try:
            return pd.read_parquet(pq), pq
        except Exception as err:  # noqa: BLE001  pyarrow raises many types for a damaged file
            raise InputError(pq, f"not a readable parquet file ({type(err).__name__}: "
                                 f"{str(err).splitlines()[0][:120] if str(err) else ''})") from None
    if csv.exists():
        check_regular(csv, "results", "results file")
        try:
            return to_frame(pd.read_csv(csv, keep_default_na=False, na_values=[""]).to_dict("records")), csv
        except (ValueError, UnicodeDecodeError, pd.errors.ParserError) as err:
            raise InputError(csv, f"not a readable results CSV ({str(err)[:120]})") from None
    raise InputError(run_dir, "no results.parquet or results.csv here (is it a `harness run` output folder?)")
