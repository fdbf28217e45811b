"""How far ``harness plan --estimate`` is from what a finished run measured
(``harness bench calibrate --check RUN_DIR``).

The run's config (its record's, ``run.json``: ``extends`` already merged) is estimated as ``plan``
does — its scenes read from their files, the unit costs from the benchmark folder — for the
workers the run had, and set against what the run measured:

* **CPU seconds**: the cold run's ``cpu_seconds`` (its process and its workers, user + system)
  against :meth:`~harness.run.estimate.Estimate.cpu_s`. The cold run is the record (``records/``)
  with the most cache misses; a rerun that computed less is not what an estimate of a cold run
  describes, so the table says when even that record had hits;
* **wall seconds**: its ``stage_seconds`` total against :meth:`~harness.run.estimate.Estimate.wall_s`,
  and the score and render stages on their own;
* **per view protocol**: the seconds the results' rows hold for each protocol — its images'
  ``render_s + metrics_s`` and its views' ``render_ref_s`` (once per scene, frame and view) —
  against the estimate's share of that protocol (:attr:`~harness.run.estimate.Estimate.protocols`:
  the same parts — the packing of a view task and its reference features are in no row);
  these are timed inside the tasks, so on a machine with no more busy threads than cores they are
  CPU seconds; on an oversubscribed one they also hold the waiting;
* **scoring**: the rows' ``score_s``, once per score task, against the score stage's core-seconds.

Reading of "within 20 % of the measured default study (CPU-s and wall, per protocol)": each row's
ratio estimate / measured must lie in [1/1.2, 1.2]; the table says it row by row. Markdown on
stdout and ``calibrate-check-<run name>.json``/``.md`` in the benchmark's ``--out``; the exit status
is 0 either way (a check to read, not a gate: the machine it ran on may have been busy).
"""

from __future__ import annotations

import contextlib
from pathlib import Path

from harness.core.paths import REPO_ROOT

TOLERANCE = 0.2


def cold_record(records: list[dict]) -> dict | None:
    """The record with the most cache misses (ties: the latest)."""
    return max(reversed(records), key=lambda r: _count(r, "misses"), default=None)


def measured(run_dir: Path) -> tuple[dict, dict, dict]:
    """(the cold record, seconds per protocol, score seconds) of a finished run."""
    from harness.core.errors import InputError
    from harness.report.record import read_records
    from harness.report.tracking import read_run

    df, _ = read_run(run_dir)
    records, _ = read_records(run_dir)
    record = cold_record(records)
    if record is None or not isinstance(record.get("config"), dict):
        raise InputError(run_dir, "no run record with its config (run.json, records/): not a `harness run` folder")
    ok = df[df["status"] == "ok"]
    per = {}
    for proto, rows in ok.groupby("protocol", sort=False):
        views = rows.drop_duplicates(["scene", "frame", "view"])
        per[str(proto)] = float(rows["render_s"].fillna(0).sum() + rows["metrics_s"].fillna(0).sum()
                                + views["render_ref_s"].fillna(0).sum())
    tasks = ok.drop_duplicates(["scene", "frame", "method", "params", "score_s"])
    return record, per, {"score": float(tasks["score_s"].fillna(0).sum())}


def rows(run_dir: Path, *, bench: Path, efficiency: float) -> tuple[list[dict], dict]:
    """One row per quantity (``what, estimate, measured, ratio, within``) and what they stand on."""
    from harness.run.config import parse_config
    from harness.run.estimate import estimate, scene_info
    from harness.run.scene_sizes import Assumptions
    from harness.run.unit_costs import from_bench
    from harness.run.view_coverage import look

    record, per_protocol, score = measured(run_dir)
    config = parse_config(record["config"], record.get("config_path") or "run.json")
    workers = int(record.get("workers") or config.workers)
    infos = [scene_info(s, config, Assumptions()) for s in config.scenes]
    look(infos, config)  # the views the run made, as plan --estimate looks at them
    est = estimate(config, infos, from_bench(bench))
    stages = record.get("stage_seconds") or {}

    walls = est.stage_walls(workers, efficiency)
    out = [("CPU seconds (cold run)", est.cpu_s(workers), record.get("cpu_seconds")),
           ("wall seconds (cold run)", est.wall_s(workers, efficiency), stages.get("total")),
           ("wall: score stage", walls["score"], stages.get("score")),
           ("wall: render and metrics stage", walls["render_metrics"], stages.get("render_metrics")),
           ("task seconds: scoring", est.stages["score"].core_s, score["score"])]
    out += [(f"task seconds: {p} views", est.protocols.get(p, 0.0), v) for p, v in per_protocol.items()]
    return [_row(*r) for r in out], _about(record, config, run_dir, bench, workers, efficiency)


def _row(what: str, estimate: float, measured) -> dict:
    """One quantity: its ratio estimate / measured and whether it is within the tolerance."""
    ratio = estimate / measured if isinstance(measured, (int, float)) and measured > 0 else None
    return {"what": what, "estimate": estimate, "measured": measured, "ratio": ratio,
            "within": ratio is not None and 1 / (1 + TOLERANCE) <= ratio <= 1 + TOLERANCE}


def _count(record: dict, key: str) -> int:
    return sum(int(c.get(key, 0)) for c in (record.get("cache_counts") or {}).values() if isinstance(c, dict))


def _about(record: dict, config, run_dir: Path, bench: Path, workers: int, efficiency: float) -> dict:
    """What a check stands on: the run (its name as a file-name part), its workers and threads, its
    cache counts, the units' folder."""
    name = "".join(c if c.isalnum() or c in "-_" else "-" for c in str(record.get("name") or config.name))
    executor = record.get("executor") if isinstance(record.get("executor"), dict) else {}
    wall, cpu = (record.get("stage_seconds") or {}).get("total"), record.get("cpu_seconds")
    busy = cpu / (workers * wall) if isinstance(cpu, (int, float)) and isinstance(wall, (int, float)) and wall > 0 \
        else None
    return {"name": name, "threads": executor.get("threads"), "run": str(run_dir), "record": record.get("when"),
            "utilisation": busy,
            "workers": workers, "efficiency": efficiency, "cache_hits": _count(record, "hits"),
            "cache_misses": _count(record, "misses"), "bench": str(bench), "config": record.get("config_path")}


def markdown(table: list[dict], info: dict) -> str:
    threads = info.get("threads") or 1
    many = "" if threads <= 1 else (f" Its workers had {threads} threads each: the estimate is for one-thread "
                                    "workers, and idle torch threads wait busily (about twice the CPU seconds).")
    cold = "" if not info["cache_hits"] else (f" — that run had {info['cache_hits']} cache hits: it was not cold, "
                                               "and measured less than a cold run takes")
    lines = [f"# harness bench calibrate --check {info['run']}", "",
             f"The run of {info['record']} ({info['config']}, {info['workers']} worker(s), {info['cache_misses']} "
             f"stages computed{cold}) against `harness plan --estimate` with the units of {info['bench']} "
             f"(parallel efficiency {info['efficiency']:g}). Within: the estimate is within "
             f"{round(100 * TOLERANCE)} % of the measurement (ratio in [{1 / (1 + TOLERANCE):.3f}, "
             f"{1 + TOLERANCE:g}]).{many} Wall and task seconds hold waiting on a machine with more busy threads "
             f"than cores{_busy(info.get('utilisation'))}.", "",
             "| quantity | estimate (s) | measured (s) | estimate / measured | within 20 % |", "|---|---|---|---|---|"]
    for r in table:
        m = "–" if r["measured"] is None else f"{r['measured']:,.1f}"
        ratio = "–" if r["ratio"] is None else f"{r['ratio']:.2f}"
        lines.append(f"| {r['what']} | {r['estimate']:,.1f} | {m} | {ratio} | {'yes' if r['within'] else 'no'} |")
    met = sum(r["within"] for r in table)
    lines += ["", f"{met} of {len(table)} within 20 %."]
    return "\n".join(lines)


def _busy(share) -> str:
    """What the run's share of its workers' cores says of its wall and task seconds."""
    if share is None:
        return ""
    return (f": this run used {100 * share:.0f} % of its workers' cores (CPU seconds / (workers × wall))"
            + (", so they hold waiting" if share < 0.8 else ""))


def check_run(run_dir, *, bench=None, efficiency: float | None = None) -> tuple[dict, str]:
    """(the comparison as JSON-able data, as markdown)."""
    from harness.core.errors import InputError
    from harness.core.paths import results_dir
    from harness.run.estimate import DEFAULT_EFFICIENCY

    efficiency = DEFAULT_EFFICIENCY if efficiency is None else efficiency
    if not 0 < efficiency <= 1:
        raise InputError("--efficiency", f"must be in (0, 1], got {efficiency}")
    bench = Path(bench) if bench else results_dir() / "bench"
    with contextlib.suppress(ValueError):  # the committed units: named from the checkout, not this machine
        bench = bench.resolve().relative_to(REPO_ROOT)
    table, info = rows(Path(run_dir), bench=bench, efficiency=efficiency)
    return {**info, "rows": table}, markdown(table, info)
