"""`harness bench executors`: the local process pool against Ray on one config, cold cache, one sitting.

Runs ``harness run CONFIG --executor E --workers W --threads 1`` as a fresh subprocess for E in
(local, ray) and W in (1, 2) — each from an empty stage cache, so every stage is computed — and
reports per run the wall time of the whole command (process start, Ray cluster start and stop,
tables and report page included: what a user waits for) and the runner's own
``stage_seconds.total`` from ``run.json`` (the stages the executor runs, without the start-up and
the outputs). One thread per worker (``--threads``), so that W workers use W cores: with the
default ``cores // workers`` threads one worker would already use both cores of this machine.

The goals, both ratios of runs taken in the same sitting (the order of the runs is
interleaved over the repeats, so a drift in the machine's load hits every variant alike):

* Ray overhead at equal workers: ``wall(ray-W) / wall(local-W) - 1`` ≤ 15 %;
* speed-up from one to two workers: ``E-1 / E-2`` ≥ 1.7, on the stages (the part workers share)
  and, for what a user sees, on the wall time, whose serial part (interpreter and imports, tables,
  plots, report page: ~10 s on ci.yaml) no executor can shorten.

Every run's ``results.csv`` must equal the first run's except the wall-clock columns; the table
says whether it did. Results: ``results/bench/executors.{json,md}`` for ci.yaml,
``executors-<config stem>.{json,md}`` for another ``--config`` (e.g. ``ctc_configs/study/scaling.yaml`` ->
``executors-scaling``, a larger workload where the fixed costs matter less).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

NAME = "executors"
HELP = ("ci.yaml (cold cache) on the local pool and on Ray with 1 and 2 workers, in one run: Ray's overhead "
        "at equal workers (goal: at most 15 percent) and the 1 -> 2 worker speed-up (goal >= 1.7x)")

#: the columns of results.csv measured by the clock (differ between any two runs)
TIMING = ["score_s", "prune_s", "render_ref_s", "render_s", "metrics_s"]
VARIANTS = (("local", 1), ("local", 2), ("ray", 1), ("ray", 2))


def add_arguments(parser) -> None:
    parser.add_argument("--config", default="ctc_configs/ci.yaml", help="run config (default ctc_configs/ci.yaml)")
    parser.add_argument("--repeats", type=int, default=1, help="cold runs per variant (median reported; default 1)")
    parser.add_argument("--timeout", type=float, default=1800, help="seconds one run may take (default 1800)")
    parser.add_argument("--threads", type=int, default=1, help="threads per worker (default 1: W workers = W cores)")


def _one_run(config: str, executor: str, workers: int, timeout: float, threads: int) -> dict:
    """One cold ``harness run`` in a fresh subprocess: wall seconds, run.json, results.csv."""
    import pandas as pd

    from harness.core.errors import InputError

    with tempfile.TemporaryDirectory(prefix="bench-exec-") as tmp:
        out, cache = Path(tmp) / "out", Path(tmp) / "cache"
        cmd = [sys.executable, "-m", "harness", "run", config, "--executor", executor, "--workers", str(workers),
               "--threads", str(threads), "--out", str(out), "--cache", str(cache)]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:] or ["(no output)"]
            raise InputError(config, f"harness run --executor {executor} --workers {workers} failed "
                                     f"(exit {proc.returncode}): {tail[0]}")
        record = json.loads((out / "run.json").read_text())
        results = pd.read_csv(out / "results.csv", keep_default_na=False, dtype=str).drop(columns=TIMING,
                                                                                           errors="ignore")
    return {"wall_s": wall, "stages_s": float(record["stage_seconds"]["total"]), "results": results,
            "executor": record.get("executor", {})}


def _median(xs: list[float]) -> float:
    import statistics

    return float(statistics.median(xs))


def summarise(walls: dict[tuple[str, int], list[float]], prefix: str = "") -> dict:
    """Overhead of Ray at equal workers and the 1 -> 2 speed-up of each executor (medians of
    ``walls``: seconds per (executor, workers)); keys ``{prefix}ray_overhead_W``, ``{prefix}speedup_E``."""
    med = {k: _median(v) for k, v in walls.items()}
    out = {}
    for w in (1, 2):
        if ("local", w) in med and ("ray", w) in med:
            out[f"{prefix}ray_overhead_{w}"] = med[("ray", w)] / med[("local", w)] - 1.0
    for e in ("local", "ray"):
        if (e, 1) in med and (e, 2) in med:
            out[f"{prefix}speedup_{e}"] = med[(e, 1)] / med[(e, 2)]
    return out


def _markdown(config: str, threads: int, runs: list[dict], walls, stages, summary: dict, identical: bool) -> str:
    cores = os.cpu_count()
    lines = [
        f"# harness bench executors ({config}, cold cache, {cores} cores, {threads} thread(s) per worker)",
        "",
        "| executor | workers | wall s (median) | stages s (median) | serial part s (wall - stages) | runs (wall s) |",
        "|---|---|---|---|---|---|",
    ]
    for (e, w) in VARIANTS:
        if (e, w) not in walls:
            continue
        wall, st = _median(walls[(e, w)]), _median(stages[(e, w)])
        lines.append(f"| {e} | {w} | {wall:.1f} | {st:.1f} | {wall - st:.1f} | "
                     f"{', '.join(f'{x:.1f}' for x in walls[(e, w)])} |")

    def goal(value, ok):
        return f"**{value}** ({'met' if ok else 'missed'})"

    lines += ["", "| quantity | stages | wall |", "|---|---|---|"]
    for w in (1, 2):
        k = f"ray_overhead_{w}"
        if k in summary:
            cells = [goal(f"{100 * summary[p + k]:+.1f} %", summary[p + k] <= 0.15) for p in ("stages_", "")]
            lines.append(f"| Ray overhead at {w} worker(s): ray / local - 1 (goal <= 15 %) | {' | '.join(cells)} |")
    for e in ("local", "ray"):
        k = f"speedup_{e}"
        if k in summary:
            cells = [goal(f"{summary[p + k]:.2f}x", summary[p + k] >= 1.7) for p in ("stages_", "")]
            lines.append(f"| {e}: speed-up 1 -> 2 workers (goal >= 1.7x) | {' | '.join(cells)} |")
    lines.append(f"| results.csv identical across all {len(runs)} runs (timing columns aside) | "
                 f"{'yes' if identical else '**no**'} | |")
    lines += ["", "Wall: the whole `harness run` command as a user waits for it (interpreter start and imports, "
              "Ray cluster start and stop, tables, plots, report page); stages: the runner's "
              "`stage_seconds.total` from run.json (what the executor runs). Runs interleaved "
              "(local-1, local-2, ray-1, ray-2, then again per repeat)."]
    return "\n".join(lines)


def run(args) -> int:
    from harness.benchmarks._common import out_dir, write_result
    from harness.core.errors import InputError

    if args.threads < 1:
        raise InputError("--threads", f"must be >= 1, got {args.threads}")
    if args.repeats < 1:
        raise InputError("--repeats", f"must be >= 1, got {args.repeats}")
    if not Path(args.config).is_file():
        raise InputError(args.config, "no such config file")
    folder = out_dir(args)  # created and probed before any work
    walls: dict = {}
    stages: dict = {}
    runs: list[dict] = []
    first = None
    identical = True
    for rep in range(args.repeats):
        for e, w in VARIANTS:
            print(f"bench executors: {e}-{w} (repeat {rep + 1}/{args.repeats}) ...", flush=True)
            r = _one_run(args.config, e, w, args.timeout, args.threads)
            print(f"  wall {r['wall_s']:.1f} s, stages {r['stages_s']:.1f} s", flush=True)
            walls.setdefault((e, w), []).append(r["wall_s"])
            stages.setdefault((e, w), []).append(r["stages_s"])
            if first is None:
                first = r["results"]
            elif not r["results"].equals(first):
                identical = False
            runs.append({"executor": e, "workers": w, "repeat": rep, "wall_s": r["wall_s"],
                         "stages_s": r["stages_s"], "executor_record": r["executor"]})
    summary = {**summarise(walls), **summarise(stages, prefix="stages_")}
    md = _markdown(args.config, args.threads, runs, walls, stages, summary, identical)
    name = "executors" if Path(args.config).stem == "ci" else f"executors-{Path(args.config).stem}"
    path = write_result(name, {"config": args.config, "threads": args.threads, "runs": runs, "summary": summary,
                                      "results_identical": identical}, md, out=folder)
    print(md)
    print(f"wrote {path}")
    return 0 if identical else 1
