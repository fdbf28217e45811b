"""Nightly metric tracking: summarise a run, keep a history, compare with a baseline.

**Summary** of a run folder (``harness run`` output: tidy ``results.parquet`` + ``run.json``):

* ``groups``: per (scene, method, variant, ratio), over the rows with ``status == "ok"``: the mean of
  every *tracked* metric — one registered with a ``tolerance`` (:mod:`harness.metrics.registry`:
  PSNR, SSIM, LPIPS) — with its sample standard deviation beside it (``psnr_std``, ``ssim_std``, ...;
  ddof = 1, null below two views); a metric that is +inf on identical renders (PSNR) is averaged
  over its *finite* values with the count of +inf views apart (``psnr_n_inf``); and the number of
  measured views. A metric the run did not measure (NaN on its every measured row) is null; one that
  is NaN on some measured views — of a group, or of a whole group while others have values — (or
  infinite where it cannot be) is an error, never averaged over the others. Key
  ``"scene|method[variant]|ratio"`` (``scene@protocol`` for a held-out view protocol other than the
  primary one).
* ``run`` (the config's name) and ``protocols`` (the held-out view protocols, primary first): what
  the run is, so it is compared only with a baseline of the same config and protocols.
* ``stages``: seconds per stage — the run's wall time per stage from ``run.json`` (``run:load``,
  ``run:score``, ...; only when the run computed everything, i.e. no stage-cache hits, since a cached
  stage measures nothing), the scoring time of each (scene, method variant) (``score:<scene>|<m>[<v>]``,
  the time of the run that computed the scores), and each scene's mean per-view render and metric
  times (``render:<scene>``, ``metrics:<scene>``).
* ``calibration_s``: the median time of :func:`calibration_workload` — a fixed numpy + torch kernel
  mix — on the same machine, taken from ``run.json["calibration_s"]`` when the runner recorded it, else
  timed by ``harness track`` itself right after the run (``calibration_source`` says which).
* ``commit`` (run.json, else ``git rev-parse HEAD``, else ``"unknown"``), ``machine``, ``when``, ``run``.

**Comparison** with a baseline file ``{"tolerances": {...}, "summary": {...}}`` of the same config
and protocols (:func:`check_like`; anything else is an error, not a list of false regressions). A
regression is

* a baseline group missing from the run or without a measured view (a pruner that errors or is skipped);
* a tracked metric moving the wrong way (its registered direction) by more than its tolerance —
  ``tolerances.<metric>``, default the registered one (PSNR 0.5 dB, SSIM 0.005, LPIPS 0.005); a group
  whose every view was +inf in the baseline (pruning changed nothing) regresses when it now has
  finite views;
* a stage whose *normalised* time t / calibration_s grew by more than the factor ``1 + tolerances.stage``
  — machine speed cancels in the ratio — when the run's stage took at least ``tolerances.min_stage_s``
  seconds (shorter stages are timer noise on a shared machine).

Groups and stages present only in the run are reported as new, never as regressions.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from harness.core.errors import InputError
from harness.metrics import registry
from harness.report.machine import describe_machine, git_commit, time_calibration

SCHEMA = 1
#: the tolerances of the stages (their time may grow by the factor 1 + stage; shorter ones are not judged)
STAGE_TOLERANCES = {"stage": 0.5, "min_stage_s": 1.0}
_RUN_STAGES = ("load", "score", "prune", "render_metrics", "aggregate", "total")


def default_tolerances() -> dict[str, float]:
    """Every tracked metric's registered tolerance, then the stages' (:data:`STAGE_TOLERANCES`).

    "Tracking takes names, directions, digits and tolerances from the registry": a metric is tracked
    when it is registered with a ``tolerance`` (PSNR, SSIM, LPIPS); one without (a plugin's, by
    default) has no scale on which a move is a regression, so it is not compared."""
    return {**{m.name: m.tolerance for m in registry.tracked()}, **STAGE_TOLERANCES}


def __getattr__(name: str):
    if name == "DEFAULT_TOLERANCES":  # the registry's, as of now (plugins' metrics included)
        return default_tolerances()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# --------------------------------------------------------------------------- summary
def group_key(scene: str, method: str, variant: str, ratio: float) -> str:
    return f"{scene}|{method}[{variant}]|{float(ratio):g}"


def _finite_or_none(x) -> float | None:
    return float(x) if x is not None and np.isfinite(x) else None


def summarize_groups(df: pd.DataFrame) -> dict[str, dict]:
    """Per (scene, method, variant, ratio) means over measured views (PSNR: finite values only); a
    held-out view protocol other than the primary one tracks its groups as ``<scene>@<protocol>``."""
    from harness.report.summary import protocol_subsets

    subsets = protocol_subsets(df)
    if len(subsets) > 1:
        out = {}
        for proto, suffix, sub in subsets:
            sub = sub if not suffix else sub[sub["protocol"] == proto].assign(scene=lambda d: d["scene"] + "@" + proto)
            out.update(summarize_groups(sub.drop(columns=["protocol"])))
        return out
    ok = df[df["status"] == "ok"]
    tracked = [m for m in registry.tracked() if m.name in df]
    measured = _measured(ok, tracked)
    out: dict[str, dict] = {}
    for (scene, method, variant, ratio), g in ok.groupby(["scene", "method", "variant", "ratio"], sort=True):
        where = f"results of {scene} / {method}[{variant}]"
        out[group_key(scene, method, variant, ratio)] = {
            "scene": scene, "method": method, "variant": variant, "ratio": float(ratio), "n_views": len(g),
            **{k: v for m in tracked for k, v in _metric_summary(g[m.name], m, where, m.name in measured).items()},
        }
    # groups the run attempted but never measured (errors, skips) are listed with n_views = 0
    for (scene, method, variant, ratio), _ in df[df["status"] != "ok"].groupby(
            ["scene", "method", "variant", "ratio"], sort=True, dropna=False):
        key = group_key(scene, method, variant, 0.0 if pd.isna(ratio) else ratio)
        out.setdefault(key, {"scene": scene, "method": method, "variant": variant,
                             "ratio": None if pd.isna(ratio) else float(ratio), "n_views": 0,
                             **{k: v for m in tracked for k, v in
                                ({m.name: None} | ({f"{m.name}_n_inf": 0} if m.inf_if_identical else {})).items()}})
    return out


def _measured(ok: pd.DataFrame, tracked) -> set[str]:
    """The metrics the run measured on some view: measured anywhere, measured everywhere (NaN on a
    group's every view is an error too, not a metric left out)."""
    return {m.name for m in tracked if pd.to_numeric(ok[m.name], errors="coerce").notna().any()}


def _metric_summary(values: pd.Series, m, where: str, measured: bool) -> dict:
    """``{name: mean, name_std: sample std}`` (+ ``name_n_inf`` for a metric that is +inf on identical
    renders: its mean and std over the finite values) of one group's views; None where the run did
    not measure it (``measured`` False: NaN on every measured row of the run) or undefined (std below
    two)."""
    v = pd.to_numeric(values, errors="coerce").to_numpy(np.float64)
    nan = np.isnan(v)
    if nan.all() and not measured:
        return {m.name: None, f"{m.name}_std": None} | ({f"{m.name}_n_inf": 0} if m.inf_if_identical else {})
    bad = nan | (np.isneginf(v) if m.inf_if_identical else np.isinf(v))
    if bad.any():
        raise InputError(where, f"{m.label} column holds NaN or {'-inf' if m.inf_if_identical else 'inf'} on "
                                "measured rows")
    if not m.inf_if_identical:
        s = pd.Series(v)
        return {m.name: _finite_or_none(s.mean()), f"{m.name}_std": _finite_or_none(s.std(ddof=1)) if v.size > 1
                else None}
    finite = v[np.isfinite(v)]
    return {m.name: float(finite.mean()) if finite.size else None,
            f"{m.name}_std": float(finite.std(ddof=1)) if finite.size > 1 else None,
            f"{m.name}_n_inf": int(v.size - finite.size)}


def summarize_stages(df: pd.DataFrame, run_json: dict) -> dict[str, float]:
    """Stage seconds (see the module docstring for the keys)."""
    stages = _run_stages(run_json)
    ok = df[df["status"] == "ok"]
    if len(ok):
        per = ok.groupby(["scene", "method", "variant"], sort=True)["score_s"].first()
        stages.update({f"score:{scene}|{method}[{variant}]": float(v)
                       for (scene, method, variant), v in per.items() if pd.notna(v)})
        for col, name in (("render_s", "render"), ("metrics_s", "metrics")):
            stages.update({f"{name}:{scene}": float(v)
                           for scene, v in ok.groupby("scene", sort=True)[col].mean().items() if pd.notna(v)})
    return stages


def _run_stages(run_json: dict) -> dict[str, float]:
    """``run:<stage>`` seconds of run.json — only when the run computed everything (no cache hit)."""
    counts = run_json.get("cache_counts") or {}
    cached = sum(int(c.get("hits", 0)) for c in counts.values()) if isinstance(counts, dict) else 0
    if cached:
        return {}
    return {f"run:{k}": float(v) for k, v in (run_json.get("stage_seconds") or {}).items()
            if k in _RUN_STAGES and v is not None and np.isfinite(v)}


def _commit(run_json: dict) -> str:
    if run_json.get("commit"):
        return str(run_json["commit"])

    return git_commit() or "unknown"


def read_run(run_dir: str | Path) -> tuple[pd.DataFrame, dict]:
    """(tidy results, run.json as a dict — empty when absent) of a run folder."""
    from harness.report.results import read_results

    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise InputError(run_dir, "is not a folder (expected a `harness run` output folder)")
    df = read_results(run_dir)
    for c in (*registry.headline(), "score_s", "render_s", "metrics_s", "view"):
        if c not in df.columns:
            raise InputError(run_dir / "results.parquet", f"results lack the column {c!r}")
    meta_path = run_dir / "run.json"
    meta = read_run_json(meta_path) if meta_path.exists() else {}
    return df, meta


def read_run_json(path: Path) -> dict:
    """A run record (``run.json``): a bounded regular file holding a JSON object whose known keys
    have the types the harness writes; anything else is an InputError."""
    from harness.io.safe import read_json

    meta = read_json(path, "json", "run record")
    if not isinstance(meta, dict):
        raise InputError(path, f"run record must be a JSON object, got {type(meta).__name__}")
    for key, types in (("name", str), ("commit", str), ("when", str), ("machine", dict),
                       ("calibration_s", (int, float)), ("stage_seconds", dict), ("cache_counts", dict),
                       ("tables", list), ("plots", list)):
        v = meta.get(key)
        if v is not None and (not isinstance(v, types) or isinstance(v, bool)):
            raise InputError(path, f"'{key}' has the wrong type ({type(v).__name__})")
    cal = meta.get("calibration_s")
    if cal is not None and not (math.isfinite(cal) and cal > 0):
        raise InputError(path, f"'calibration_s' must be a positive number, got {cal!r}")
    _check_entries(path, meta)
    return meta


def _check_entries(path: Path, meta: dict) -> None:
    """Every ``stage_seconds`` entry a number (or null), every ``cache_counts`` entry an object."""
    for k, v in (meta.get("stage_seconds") or {}).items():
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))):
            raise InputError(path, f"'stage_seconds.{k}' is not a number")
    for k, v in (meta.get("cache_counts") or {}).items():
        if not isinstance(v, dict):
            raise InputError(path, f"'cache_counts.{k}' is not an object")


def build_summary(df: pd.DataFrame, run_json: dict, calibration_s: float | None = None) -> dict:
    """The summary of one run (module docstring). ``calibration_s`` overrides run.json's."""
    source = "given"
    if calibration_s is None and run_json.get("calibration_s"):
        calibration_s, source = float(run_json["calibration_s"]), "run.json"
    elif calibration_s is None:
        calibration_s, source = time_calibration(), "track"
    machine = run_json.get("machine")
    if not machine:
        machine = describe_machine()
    from harness.report.summary import protocol_subsets

    return {
        "schema": SCHEMA,
        "run": run_json.get("name") or (str(df["run"].iloc[0]) if len(df) else ""),
        "protocols": [p for p, _, _ in protocol_subsets(df) if p],
        "when": run_json.get("when") or time.strftime("%Y-%m-%dT%H:%M:%S"),
        "commit": _commit(run_json),
        "machine": machine,
        "calibration_s": float(calibration_s),
        "calibration_source": source,
        "groups": summarize_groups(df),
        "stages": summarize_stages(df, run_json),
    }


# --------------------------------------------------------------------------- comparison
def protocols_of(summary: dict) -> list[str]:
    """A summary's held-out view protocols; a summary from before they were recorded: ``rig`` and
    those its group keys name (``scene@protocol``)."""
    if summary.get("protocols"):
        return list(summary["protocols"])
    named = sorted({k.split("|", 1)[0].partition("@")[2] for k in summary.get("groups", {})} - {""})
    return ["rig", *named]


def check_like(baseline: dict, summary: dict, baseline_path, run_dir) -> None:
    """InputError unless the run and the baseline are of the same config and protocols: comparing
    a ci run with the nightly baseline reported 74 false regressions."""
    base = baseline["summary"]
    mine, theirs = (summary.get("run"), protocols_of(summary)), (base.get("run"), protocols_of(base))
    if mine != theirs:
        raise InputError(
            baseline_path,
            f"is a baseline of config {theirs[0]!r} (protocols {', '.join(theirs[1])}), "
            f"but {run_dir} is a run of config {mine[0]!r} (protocols {', '.join(mine[1])}); "
            "track compares a run only with a baseline of the same config and protocols "
            "(give that one with --baseline)",
        )


@dataclass(frozen=True)
class Finding:
    kind: str      # "regression" | "ok" | "new" | "note"
    key: str
    message: str


def _metric_findings(key: str, base: dict, cur: dict | None, tol: dict) -> list[Finding]:
    if cur is None or cur.get("n_views", 0) == 0:
        if base.get("n_views", 0) == 0:
            return []
        return [Finding("regression", key, f"{key}: measured on {base['n_views']} views in the baseline, "
                                           "no measured view now (error or skip)")]
    return [f for m in registry.tracked() if m.name in tol for f in _moved(key, m, base, cur, tol[m.name])]


def _moved(key: str, m, base: dict, cur: dict, tol: float) -> list[Finding]:
    """How metric ``m`` of a group moved from the baseline: ``ok`` or ``regression`` (more than
    ``tol`` the wrong way), printed with one decimal more than its tables show."""
    b, c, k = base.get(m.name), cur.get(m.name), m.digits + 1
    unit = f" {m.unit}" if m.unit else ""
    inf_before = m.inf_if_identical and b is None and base.get(f"{m.name}_n_inf", 0) > 0
    if inf_before and c is not None:
        return [Finding("regression", key, f"{key}: {m.label} was +inf on every view (identical renders), now "
                                           f"{c:.{k}f}{unit} on {cur['n_views'] - cur[f'{m.name}_n_inf']} views")]
    if b is None or c is None:
        return []
    d = c - b
    worse = -d if m.higher_is_better else d
    bound = f"{'-' if m.higher_is_better else '+'}{tol}"
    return [Finding("regression" if worse > tol else "ok", key,
                    f"{key}: {m.label} {b:.{k}f} -> {c:.{k}f}{unit} ({d:+.{k}f}, tolerance {bound})")]


def _stage_findings(base: dict, cur: dict, tol: dict) -> list[Finding]:
    out = []
    cb, cc = base["calibration_s"], cur["calibration_s"]
    for key, tb in sorted(base["stages"].items()):
        tc = cur["stages"].get(key)
        if tc is None:
            out.append(Finding("note", key, f"stage {key}: in the baseline, not timed in this run"))
            continue
        rb, rc = tb / cb, tc / cc
        if tc < tol["min_stage_s"]:
            continue
        factor = rc / rb if rb > 0 else math.inf
        kind = "regression" if factor > 1.0 + tol["stage"] else "ok"
        out.append(Finding(kind, key, f"stage {key}: {tb:.2f} s -> {tc:.2f} s, normalised {rb:.2f} -> {rc:.2f} "
                                      f"calibration units (x{factor:.2f}, tolerance x{1.0 + tol['stage']:.2f})"))
    return out


def compare(baseline: dict, summary: dict) -> list[Finding]:
    """Findings of ``summary`` against ``baseline`` (``{"tolerances", "summary"}``)."""
    tol = {**default_tolerances(), **(baseline.get("tolerances") or {})}
    base = baseline["summary"]
    out: list[Finding] = []
    for key, g in sorted(base["groups"].items()):
        out += _metric_findings(key, g, summary["groups"].get(key), tol)
    for key in sorted(set(summary["groups"]) - set(base["groups"])):
        out.append(Finding("new", key, f"{key}: not in the baseline"))
    out += _stage_findings(base, summary, tol)
    return out


# --------------------------------------------------------------------------- files
def load_baseline(path: str | Path) -> dict:
    """A baseline file, checked: tolerances must be finite non-negative numbers (a NaN tolerance
    would make every comparison pass), the calibration a positive number."""
    from harness.io.safe import read_json

    path = Path(path)
    data = read_json(path, "json", "baseline", record=False)  # state that --update-baseline rewrites
    if not isinstance(data, dict) or not isinstance(data.get("summary"), dict) \
            or not isinstance(data["summary"].get("groups"), dict) or "calibration_s" not in data["summary"]:
        raise InputError(path, "not a tracking baseline (expected {'tolerances': ..., 'summary': {...}} as "
                               "written by `harness track --update-baseline`)")
    _check_tolerances(path, data.get("tolerances") or {})
    cal = data["summary"]["calibration_s"]
    if not _number(cal) or cal <= 0:
        raise InputError(path, f"summary.calibration_s must be a positive number, got {cal!r}")
    if not isinstance(data["summary"].get("stages", {}), dict):
        raise InputError(path, "summary.stages must be an object")
    _check_groups(path, data["summary"]["groups"])
    return data


def _number(v) -> bool:
    """Is ``v`` a finite number (never a bool)?"""
    return not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)


def _check_tolerances(path: Path, tol) -> None:
    """Known names (the tracked metrics' and the stages'), each a finite number >= 0: a NaN tolerance
    would make every comparison pass."""
    if not isinstance(tol, dict):
        raise InputError(path, "'tolerances' must be an object")
    known = default_tolerances()
    unknown = sorted(set(tol) - set(known))
    if unknown:
        raise InputError(path, f"unknown tolerance(s) {', '.join(unknown)}; known: {', '.join(known)}")
    for k, v in tol.items():
        if not _number(v) or v < 0:
            raise InputError(path, f"tolerance {k!r} must be a finite number >= 0, got {v!r}")


def _check_groups(path: Path, groups: dict) -> None:
    """Every group an object whose tracked metrics are finite numbers or null."""
    for key, g in groups.items():
        if not isinstance(g, dict):
            raise InputError(path, f"group {key!r} is not an object")
        for m in (m.name for m in registry.tracked()):
            v = g.get(m)
            if v is not None and not _number(v):
                raise InputError(path, f"group {key!r}: {m} must be a finite number or null, got {v!r}")


def write_baseline(path: str | Path, summary: dict, tolerances: dict | None = None) -> Path:
    """Write ``{"tolerances", "summary"}`` atomically (tolerances default to the module's)."""
    from harness.io.files import atomic_write_text

    path = Path(path)
    payload = {"tolerances": {**default_tolerances(), **(tolerances or {})}, "summary": summary}
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(path, json.dumps(payload, indent=2, sort_keys=True, allow_nan=False) + "\n")
    except OSError as err:
        raise InputError(path, f"cannot write the baseline: {err.strerror or err}") from None
    return path


def append_history(history_dir: str | Path, summary: dict) -> Path:
    """Append ``summary`` as one JSON line to ``<history_dir>/history.jsonl``."""
    from harness.io.files import append_line

    d = Path(history_dir)
    path = d / "history.jsonl"
    line = json.dumps(summary, sort_keys=True, allow_nan=False) + "\n"
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(path, f"cannot append to the history: {err.strerror or err}") from None
    return append_line(path, line)  # one write of one line (readers see whole lines); no FIFO, no symlink
