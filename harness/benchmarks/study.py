"""`harness bench study`: CPU-seconds per stage of a study run cold and of its cached rerun, and the
fixed costs around them (a worker's start-up, the code-version digests), optionally against another
checkout of the project in the same sitting.

Each run is a fresh ``harness run CONFIG`` subprocess started in a checkout's root (so that
checkout's code runs) with its own empty stage cache; the rerun reuses that cache and output
folder, so it computes nothing. Per run: wall seconds and CPU-seconds of the whole process tree
(``getrusage`` of the waited-for children: pool workers included), and per runner stage the
CPU-seconds measured around the runner's own stage calls (``Runner._timed``, patched in by a small
probe: the same measurement for any checkout). With ``--workers 1`` (the default) every task runs in
the driver process, so a stage's CPU-seconds are all of its work; with more workers the pool's CPU
is counted when the pool is joined, after the last stage. ``outside the stages`` is the rest:
interpreter start-up, config and device checks, results, tables, plots, contact sheets, run
record, report page (and the pool's workers with ``--workers`` > 1).

``--against DIR`` runs the same sequence for the checkout in DIR (e.g. ``git worktree add
/tmp/base <commit>`` with a ``.venv`` link), alternating with this one over ``--repeats``, so both
see the same machine load; their tables are compared file by file (the runtime tables aside).
Results: ``<out>/study.{json,md}`` for ci.yaml, ``study-<config stem>`` otherwise (``--out``,
default ``runs/bench``). ``--device DEV`` measures a study on one device instead (seconds per stage,
images/s, GPU memory, its tables against a CPU run of a subset): :mod:`._study_device`.
Goals (reported, not enforced): cached rerun of ci.yaml
≤ 5 s, of default.yaml ≤ 10 s; default study cold ≤ 2,200 CPU-s.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path

from harness.benchmarks._common import run_python

NAME = "study"
HELP = ("CPU-seconds per stage of a study cold and of its cached rerun, a worker's start-up and the "
        "code-version digests; --against DIR compares another checkout in the same sitting")
STAGES = ("load", "score", "prune", "render_metrics", "aggregate")
#: table files that hold measured times (they differ between any two runs)
RUNTIME_TABLES = ("runtime", "summary")
GOALS = {"ci": ("cached", 5.0), "default": ("cached", 10.0)}

#: run inside the checkout: `harness run ...` with each runner stage's CPU-seconds written to a file
PROBE = """
import json, os, resource, sys
def cpu():
    who = (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)
    return sum(r.ru_utime + r.ru_stime for r in map(resource.getrusage, who))
from harness.run import runner
timed, stages = runner.Runner._timed, {}
def probe(self, stage, fn, *args):
    t0 = cpu()
    try:
        return timed(self, stage, fn, *args)
    finally:
        stages[stage] = stages.get(stage, 0.0) + cpu() - t0
runner.Runner._timed = probe
from harness.cli import main
code = main(sys.argv[1:])
with open(os.environ["HARNESS_BENCH_PROBE"], "w") as f:
    json.dump({"stages": stages}, f)
sys.exit(code)
"""
#: what a pool worker does before its first task: thread caps and preloads, the metric suite with
#: LPIPS, the GL renderer's context
STARTUP = """
import resource
from harness.run.tasks import init_worker
from harness.run.toolkit import Toolkit
t = Toolkit()
init_worker(1, t.imports, t.preload)
t.make_metrics(("psnr", "ssim", "lpips"), "cpu")
r = t.make_renderer("gl", "cpu")
r._ensure_context()
r.close()
u = resource.getrusage(resource.RUSAGE_SELF)
print(u.ru_utime + u.ru_stime)
"""
#: the code-version digests a run takes when it starts (every registered pruner's)
VERSIONS = """
import resource
from harness.run.toolkit import Toolkit
from harness.run.cache.versions import Versions
from methods.registry import list_pruners
before = resource.getrusage(resource.RUSAGE_SELF)
v = Versions.of(Toolkit())
[v.pruner(s.name) for s in list_pruners()]
u = resource.getrusage(resource.RUSAGE_SELF)
print(u.ru_utime + u.ru_stime - before.ru_utime - before.ru_stime)
"""


def add_arguments(parser) -> None:
    parser.add_argument("config_file", nargs="?", default=None, metavar="CONFIG",
                        help="run config (the same as --config)")
    parser.add_argument("--config", default=None, help="run config (default ctc_configs/ci.yaml)")
    parser.add_argument("--device", default=None,
                        help="measure the study on this device instead (cpu, cuda, cuda:N): seconds per stage, "
                             "images/s, GPU memory, and its tables against a CPU run of a subset "
                             "(harness/benchmarks/_study_device.py)")
    parser.add_argument("--scenes", default=None, metavar="SCENE[,SCENE]",
                        help="with --device: the study on these scenes of the config only (default: all)")
    parser.add_argument("--check", default=None, metavar="SCENE[,SCENE]",
                        help="with --device: the scenes of the CPU check (default: the config's smallest; "
                             "'none' skips it)")
    parser.add_argument("--against", default=None, metavar="DIR",
                        help="another checkout of the project to measure in the same sitting (e.g. a git worktree "
                             "of an earlier commit with a .venv link)")
    parser.add_argument("--repeats", type=int, default=1, help="cold + cached runs per checkout (median; default 1)")
    parser.add_argument("--workers", type=int, default=1,
                        help="--workers of the runs (default 1: every stage's CPU-seconds are exact)")
    parser.add_argument("--timeout", type=float, default=7200, help="seconds one run may take (default 7200)")


def _run(checkout: Path, config: Path, folder: Path, workers: int, timeout: float) -> dict:
    probe = folder / "probe.json"
    args = [
        "run",
        str(config),
        "--workers",
        str(workers),
        "--cache",
        str(folder / "cache"),
        "--out",
        str(folder / "out"),
    ]
    _, wall, cpu = run_python(checkout, PROBE, args, {"HARNESS_BENCH_PROBE": str(probe)}, timeout)
    measured = json.loads(probe.read_text())
    stages = {k: measured["stages"].get(k, 0.0) for k in STAGES}
    record = json.loads((folder / "out" / "run.json").read_text())
    counts = record.get("cache_counts") or {}
    return {"wall_s": wall, "cpu_s": cpu, "stage_cpu_s": stages, "outside_cpu_s": cpu - sum(stages.values()),
            "stage_wall_s": record.get("stage_seconds", {}),
            "misses": sum(int(c.get("misses", 0)) for c in counts.values())}


def _tables(out: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted((out / "tables").glob("*"))
            if p.is_file() and not p.name.startswith(RUNTIME_TABLES)}


def _per_image(out: Path, cold: dict) -> dict:
    import pandas as pd

    df = pd.read_csv(out / "results.csv")
    ok = df[df["status"] == "ok"] if "status" in df else df
    n = len(ok)
    return {"images": n, "render_metrics_cpu_s": cold["stage_cpu_s"]["render_metrics"] / n if n else None,
            "render_s": float(ok["render_s"].median()) if n else None,
            "metrics_s": float(ok["metrics_s"].median()) if n else None}


def _measure(checkout: Path, config: Path, workers: int, timeout: float) -> dict:
    with tempfile.TemporaryDirectory(prefix="bench-study-") as tmp:
        folder = Path(tmp)
        cold = _run(checkout, config, folder, workers, timeout)
        cached = _run(checkout, config, folder, workers, timeout)
        tables, per_image = _tables(folder / "out"), _per_image(folder / "out", cold)
    startup = float(run_python(checkout, STARTUP)[0].stdout.split()[-1])
    versions = float(run_python(checkout, VERSIONS)[0].stdout.split()[-1])
    return {"cold": cold, "cached": cached, "per_image": per_image, "worker_startup_cpu_s": startup,
            "versions_cpu_s": versions, "tables": tables}


def _median(xs):
    import statistics

    return float(statistics.median(xs))


def _figures(runs: list[dict]) -> dict:
    """The medians over repeats of every number the report shows."""
    def m(path):
        vals = []
        for r in runs:
            v = r
            for k in path:
                v = v[k]
            vals.append(v)
        return _median(vals) if None not in vals else None

    rows = {"cold CPU-s (whole run)": ("cold", "cpu_s"), "cold wall s": ("cold", "wall_s")}
    rows.update({f"cold {s} CPU-s": ("cold", "stage_cpu_s", s) for s in STAGES})
    rows.update({"cold outside the stages CPU-s": ("cold", "outside_cpu_s"),
                 "cached rerun CPU-s (whole run)": ("cached", "cpu_s"), "cached rerun wall s": ("cached", "wall_s")})
    rows.update({f"cached {s} CPU-s": ("cached", "stage_cpu_s", s) for s in STAGES})
    rows.update({"cached outside the stages CPU-s": ("cached", "outside_cpu_s"),
                 "render+metrics CPU-s per image": ("per_image", "render_metrics_cpu_s"),
                 "render s per image (median, wall)": ("per_image", "render_s"),
                 "metrics s per image (median, wall)": ("per_image", "metrics_s"),
                 "worker start-up CPU-s": ("worker_startup_cpu_s",), "code-version digests CPU-s": ("versions_cpu_s",)})
    return {label: m(path) for label, path in rows.items()}


def _markdown(config: str, workers: int, names: list[str], figs: dict, repeats: int, tables_note: str,
              goal: str) -> str:
    head = " | ".join(names) + (" | ratio (this / other)" if len(names) == 2 else "")
    lines = [f"# harness bench study ({config}, --workers {workers}, {os.cpu_count()} cores, median of {repeats})", "",
             f"| quantity | {head} |", "|---|" + "---|" * (len(names) + (len(names) == 2))]
    for label in figs[names[0]]:
        vals = [figs[n][label] for n in names]
        cells = [f"{v:.3f}" if v is not None and v < 10 else f"{v:.1f}" if v is not None else "–" for v in vals]
        if len(names) == 2 and None not in vals and vals[1]:
            cells.append(f"{vals[0] / vals[1]:.2f}")
        elif len(names) == 2:
            cells.append("–")
        lines.append(f"| {label} | {' | '.join(cells)} |")
    lines += ["", tables_note, goal, "",
              "CPU-s: user + system seconds of the whole process tree (pool workers included), or of the driver "
              "process within each runner stage; a stage's CPU-s are all of its work with --workers 1. Runs alternate "
              "between the checkouts, each from an empty stage cache, then once more on that cache (the cached rerun)."]
    return "\n".join(lines)


def run(args) -> int:
    from harness.benchmarks._common import out_dir, write_result
    from harness.core.errors import InputError

    folder = out_dir(args)  # created and probed before any work
    if args.config_file and args.config and Path(args.config_file) != Path(args.config):
        raise InputError("--config", f"two configs given ({args.config_file} and {args.config}); give one")
    args.config = args.config_file or args.config or "ctc_configs/ci.yaml"
    if args.repeats < 1:
        raise InputError("--repeats", f"must be >= 1, got {args.repeats}")
    if not 1 <= args.workers <= 256:
        raise InputError("--workers", f"must be 1..256, got {args.workers}")
    config = Path(args.config).resolve()
    if not config.is_file():
        raise InputError(args.config, "no such config file")
    if args.device is not None:
        if args.against is not None or args.repeats != 1:
            raise InputError("--device", "measures one checkout once: leave out --against and --repeats")
        from harness.benchmarks._study_device import run_device

        return run_device(args, folder, config)
    here = Path(__file__).resolve().parents[2]
    checkouts = {"this": here}
    if args.against is not None:
        other = Path(args.against).resolve()
        if not (other / "harness" / "__main__.py").is_file():
            raise InputError(args.against, "is not a checkout of this project (no harness/__main__.py)")
        checkouts["other"] = other
    runs: dict[str, list[dict]] = {n: [] for n in checkouts}
    for rep in range(args.repeats):
        for name, path in checkouts.items():
            print(f"bench study: {name} ({path}), repeat {rep + 1}/{args.repeats} ...", flush=True)
            r = _measure(path, config, args.workers, args.timeout)
            print(f"  cold {r['cold']['cpu_s']:.1f} CPU-s, cached rerun {r['cached']['cpu_s']:.1f} CPU-s "
                  f"({r['cached']['misses']} misses)", flush=True)
            runs[name].append(r)
    figs = {n: _figures(rs) for n, rs in runs.items()}
    tables = {n: rs[0]["tables"] for n, rs in runs.items()}
    stable = all(r["tables"] == rs[0]["tables"] for rs in runs.values() for r in rs)
    note = f"Tables identical across repeats (runtime tables aside): {'yes' if stable else '**no**'}."
    if "other" in tables:
        differ = sorted(k for k in set(tables["this"]) | set(tables["other"])
                        if tables["this"].get(k) != tables["other"].get(k))
        note += (" Tables of the two checkouts: " + ("byte-identical." if not differ else
                                                     f"{len(differ)} files differ: {', '.join(differ)}."))
    stem = config.stem
    kind, limit = GOALS.get(stem, (None, None))
    goal = "" if kind is None else (f"Goal: {kind} rerun of {stem}.yaml <= {limit:g} s; this checkout: "
                                    f"{figs['this']['cached rerun CPU-s (whole run)']:.1f} CPU-s, "
                                    f"{figs['this']['cached rerun wall s']:.1f} s wall.")
    md = _markdown(args.config, args.workers, list(checkouts), figs, args.repeats, note, goal)
    payload = {"config": args.config, "workers": args.workers, "repeats": args.repeats,
               "checkouts": {n: str(p) for n, p in checkouts.items()}, "figures": figs,
               "runs": {n: [{k: v for k, v in r.items() if k != "tables"} for r in rs] for n, rs in runs.items()},
               "tables_stable": stable, "tables": tables}
    name = "study" if stem == "ci" else f"study-{stem}"
    path = write_result(name, payload, md, out=folder)
    print(md)
    print(f"wrote {path}")
    return 0
