"""What a run leaves behind, and the summary printed at its end.

Run folder layout::

    <out>/results.parquet, results.csv   tidy rows (harness.report.results)
    <out>/tables/*.md|csv|tex            the paper's tables (harness.report.tables)
    <out>/plots/*.png                    curves and image grids (harness.report.plots)
    <out>/images/<scene>/...png          reference and figure renders (inputs of the image grids)
    <out>/contact_sheets/<scene>.png     held-out views of each scene
    <out>/run.json                       config, commit, machine, stage times, cache hits/misses,
                                         skips and errors of the latest run
    <out>/records/<when>-<pid>.json      the same record of every run into this folder (a cached
                                         rerun adds one and never replaces the cold run's)

Everything is derived from the content-addressed stage cache (default ``<harness cache>/stages``),
so ``harness tables RUN_DIR`` can rebuild tables and plots from ``results.parquet`` and ``images/``.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

from harness.core import jsonout
from harness.core.names import file_name
from harness.io.files import atomic_write_bytes, atomic_write_text
from harness.io.safe import read_bytes
from harness.report.machine import (
    cpu_seconds,
    describe_machine,
    git_commit,
    time_calibration,
)

#: scene, method, variant and frame names in file names: the one injective map (:mod:`harness.core.names`)
slug = file_name


def image_name(method: str, variant: str, ratio: float) -> str:
    """``<method>__<variant>__r<ratio>.png`` (``input.png``, ``photo.png``): the ratio to two decimals
    when that is exact, else to nine (two ratios never share a file)."""
    if method in ("input", "photo"):
        return f"{method}.png"
    r = f"{ratio:.2f}" if round(ratio, 2) == round(ratio, 9) else f"{ratio:.9g}"
    return f"{file_name(method)}__{file_name(variant)}__r{r}.png"


def copy_images(images: dict, out_dir: Path) -> Path:
    """Copy figure renders from the cache into ``<out>/images/<scene>[/<frame>]/``."""
    root = Path(out_dir) / "images"
    for (scene, frame, method, variant, ratio), src in images.items():
        src = Path(src)
        if not src.exists():
            continue
        dst = root / slug(scene) / (slug(frame) if frame else "") / image_name(method, variant, ratio)
        atomic_write_bytes(dst, read_bytes(src, "image", "cached image", record=False))  # the one write path
    return root


def contact_sheets(items, cache, ref_key, out_dir: Path, background=(0.0, 0.0, 0.0)) -> dict[str, list[float]]:
    """One labelled grid of the held-out reference renders per scene (first frame), via
    :class:`harness.views.contact_sheet.ContactSheet`, reading one render at a time; returns each
    scene's per-view coverage."""
    from harness.views.contact_sheet import ContactSheet

    out: dict[str, list[float]] = {}
    for item in items:
        if item.spec.name in out or not item.test:
            continue
        sheet = ContactSheet(len(item.primary_views()), background=background)
        for cam in item.primary_views():
            image = cache.load_array("render_ref", ref_key(item, cam))
            if image is not None:
                sheet.add(image, cam.name)
        if not sheet.covs:
            continue
        path = Path(out_dir) / "contact_sheets" / f"{slug(item.spec.name)}.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        out[item.spec.name] = sheet.write(path)
    return out


#: the page lists at most this many run records (the newest)
MAX_RECORDS = 200


def write_run_json(out_dir: Path, config, result, *, workers: int, cache_root: Path, argv=None,
                   latest: bool = True) -> Path:
    """run.json, with the calibration workload timed right after the run (``harness track`` divides
    stage times by it, so machine speed cancels out of the regression check); the same record is
    kept as ``records/<when>-<pid>.json``, so every run into the folder stays visible. ``latest``
    False: the record only (a run that replaced no results leaves run.json to the run that did);
    returns the path written last."""
    status = [r.get("status") for r in result.rows]
    payload = {
        "name": config.name,
        "config_path": config.source_path,
        "config": config.raw,
        "when": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "commit": git_commit(),
        "machine": describe_machine(),
        "workers": workers,
        "executor": getattr(result, "executor", None) or {"name": "local", "workers": workers},
        "cache": str(cache_root),
        "stage_seconds": result.stage_s,
        "cpu_seconds": cpu_seconds(),
        "calibration_s": time_calibration(),
        "cache_counts": result.counts,
        "skipped": [s.__dict__ for s in result.skips],
        "errors": result.errors,
        "tables": list(config.tables),
        "plots": list(config.plots),
        "anchor": config.anchor,
        "rows": {k: status.count(k) for k in ("ok", "skipped", "error")},
        "argv": argv or [],
    }
    text = jsonout.dumps(payload, indent=2) + "\n"
    records = Path(out_dir) / "records"
    records.mkdir(exist_ok=True)
    path = records / f"{time.strftime('%Y%m%dT%H%M%S')}-{os.getpid()}.json"
    atomic_write_text(path, text)
    if latest:
        path = Path(out_dir) / "run.json"
        atomic_write_text(path, text)
    return path


def read_records(run_dir: Path) -> tuple[list[dict], list[str]]:
    """(every run record of ``<run>/records/`` — oldest first, the newest :data:`MAX_RECORDS` —, one
    line per record file that could not be read). A folder from before records existed gives its
    ``run.json`` alone. An unreadable record is named, not fatal: the page shows the others."""
    from harness.core.errors import InputError
    from harness.report.tracking import read_run_json

    run_dir = Path(run_dir)
    files = sorted(run_dir.glob("records/*.json"))[-MAX_RECORDS:]
    if not files and (run_dir / "run.json").is_file():
        files = [run_dir / "run.json"]
    out, bad = [], []
    for f in files:
        try:
            out.append(read_run_json(f))
        except InputError as err:
            bad.append(str(err))
    return out, bad


def summary_lines(result, df, paths: dict) -> list[str]:
    """The closing summary: rows, skips, errors, cache hits/misses, stage times, where things are."""
    n = {k: int((df["status"] == k).sum()) if len(df) else 0 for k in ("ok", "skipped", "error")}
    ok = n["ok"]
    lines = [f"rows: {len(df)} ({ok} measured, {n['skipped']} skipped, {n['error']} errors)"]
    hits = sum(c["hits"] for c in result.counts.values())
    misses = sum(c["misses"] for c in result.counts.values())
    per = ", ".join(f"{s} {c['hits']}/{c['misses']}" for s, c in result.counts.items())
    lines.append(f"cache: {hits} hits, {misses} misses (hits/misses per stage: {per or 'none'})")
    lines.append("stage seconds: " + ", ".join(f"{k} {v:.1f}" for k, v in result.stage_s.items())
                 + f"; CPU seconds (all processes) {cpu_seconds():.1f}")
    if ok:
        from harness.report.stats import NEAR_IDENTICAL_DB, near_identical

        m = df[df["status"] == "ok"]
        near = near_identical(m, m.columns)  # every dB metric the rows carry (the metric registry)
        informative = m.loc[~near, "psnr"].astype(float)
        lines.append(f"PSNR over measured pairs: mean {informative.mean():.2f} dB, median "
                     f"{m['psnr'].astype(float).median():.2f} dB ({int(near.sum())} near-identical pairs, "
                     f"PSNR >= {NEAR_IDENTICAL_DB:g} dB or inf, left out of the mean)")
    for s in result.skips:
        what = s.scene if s.method == "*" else f"{s.scene} / {s.method}[{s.variant}]"
        lines.append(f"skipped {what}: {s.reason}")
    for e in result.errors[:20]:
        lines.append(f"error: {e}")
    for name, p in paths.items():
        lines.append(f"{name:<15} {p}")
    return lines
