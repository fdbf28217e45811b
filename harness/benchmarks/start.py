"""`harness bench start`: what everyday commands cost as whole processes — start-up included.

Each command runs as a fresh child process (``python -m harness …``); its wall time (from spawn to
exit) and its own CPU seconds and peak resident memory (``os.wait4``: that child's rusage, not a
running maximum over all children; spawned from a small launcher, :data:`LAUNCHER`) are recorded. A bare ``python -c
"import numpy"`` runs in every round as the floor every command stands on.

``--against DIR`` times a second checkout (e.g. a worktree of an earlier commit) with the same
interpreter in the same sitting: ``python -m harness`` run in DIR imports DIR's code. Rounds
alternate the order of the two trees (ABBA) so drift in the machine's load falls on both; a first
round warms the page cache and numba's kernel cache and is not counted. Per command: median and
range over the rounds of each tree, and the median of the per-round ratios (this tree / DIR), the
only figure that compares the two on a shared machine. The 1-minute load average is recorded with
every sample.

The commands (their goals on a quiet 2-core machine, this tree): ``harness prune bonsai-7k
OUT.ply --ratio 0.3`` ≤ 1.5 s and ≤ 600 MiB; ``harness info luigi`` and ``harness --help`` ≤ 0.3 s;
``harness prune luigi``; and ``harness prune bonsai-7k --reading v1``, so that the default reading's
cost is compared with v1's in the same rounds (the command's own ``score`` seconds are kept too).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

NAME = "start"
HELP = "process wall time and peak memory of prune/info/--help against a bare interpreter (--against another checkout)"
BASELINE = "python -c 'import numpy'"
#: command -> (harness arguments, goal seconds, goal MiB); OUT is replaced by a temporary file
COMMANDS = {
    "harness --help": (["--help"], 0.3, None),
    "harness info luigi": (["info", "luigi"], 0.3, None),
    "harness prune luigi": (["prune", "luigi", "OUT", "--ratio", "0.3", "--json"], None, None),
    "harness prune bonsai-7k": (["prune", "bonsai-7k", "OUT", "--ratio", "0.3", "--json"], 1.5, 600.0),
    "harness prune bonsai-7k --reading v1": (["prune", "bonsai-7k", "OUT", "--ratio", "0.3", "--reading", "v1",
                                              "--json"], None, None),
}


def add_arguments(parser) -> None:
    parser.add_argument("--repeats", type=int, default=5, help="counted rounds (default 5; one warm-up round more)")
    parser.add_argument("--against", metavar="DIR", default=None,
                        help="another checkout to time in the same rounds (its `python -m harness`)")
    parser.add_argument("--only", action="append", default=None, metavar="COMMAND",
                        help=f"time only these commands (repeatable): {', '.join(COMMANDS)}")


@dataclass
class Sample:
    wall_s: float
    cpu_s: float
    peak_mib: float
    load: float
    score_s: float | None = None  # a prune's own score stage (its --json report)


#: started by :func:`run_child` to start the measured command: a bare interpreter (``-I -S``, ~9 MiB)
#: whose child is timed from spawn to exit and read with ``os.wait4``. A child's peak memory counts
#: the memory of the process that spawned it (spawn shares it until exec), so it is spawned from
#: this launcher, not from the benchmark's own, larger process.
LAUNCHER = """
import os, sys, time
report, cwd, *argv = sys.argv[1:]
os.chdir(cwd)
t0 = time.perf_counter()
pid = os.posix_spawn(argv[0], argv, os.environ)
_, status, usage = os.wait4(pid, 0)
wall = time.perf_counter() - t0
with open(report, "w") as f:
    f.write(repr((os.waitstatus_to_exitcode(status), wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss)))
"""


def run_child(argv: list[str], cwd: Path) -> tuple[Sample, str]:
    """Run ``argv`` in ``cwd`` to its exit; (its sample, its stdout). A failure is an error."""
    import ast

    with tempfile.TemporaryDirectory() as tmp:
        report = Path(tmp) / "report"
        done = subprocess.run([sys.executable, "-I", "-S", "-c", LAUNCHER, str(report), str(cwd), *argv],
                              capture_output=True, text=True, errors="replace", stdin=subprocess.DEVNULL)
        if done.returncode != 0 or not report.is_file():
            raise RuntimeError(f"the launcher of {' '.join(argv)} failed: {done.stderr.strip()[-500:]}")
        status, wall, cpu, peak_kib = ast.literal_eval(report.read_text())
    if status != 0:
        raise RuntimeError(f"{' '.join(argv)} (in {cwd}) exited {status}: {done.stderr.strip()[-500:]}")
    return Sample(wall, cpu, peak_kib / 1024.0, os.getloadavg()[0]), done.stdout


def _command(name: str, output: Path) -> list[str]:
    if name == BASELINE:
        return [sys.executable, "-c", "import numpy"]
    args = [str(output) if a == "OUT" else a for a in COMMANDS[name][0]]
    return [sys.executable, "-m", "harness", *args]


def measure(trees: dict[str, Path], names: list[str], repeats: int, log=print) -> dict:
    """{tree: {command: [Sample, ...]}} over ``repeats`` counted rounds (module docstring)."""
    samples: dict[str, dict[str, list[Sample]]] = {t: {n: [] for n in names} for t in trees}
    samples["-"] = {BASELINE: []}
    with tempfile.TemporaryDirectory() as tmp:
        for round_ in range(repeats + 1):
            order = list(trees) if round_ % 2 == 0 else list(reversed(trees))
            steps = [("-", BASELINE)] + [(t, n) for n in names for t in order]
            for tree, name in steps:
                cwd = trees.get(tree, next(iter(trees.values())))
                sample, stdout = run_child(_command(name, Path(tmp) / f"out-{tree}.ply"), cwd)
                if name.startswith("harness prune"):
                    sample.score_s = json.loads(stdout)["seconds"].get("score")
                if round_ > 0:  # round 0 warms caches
                    samples[tree][name].append(sample)
            log(f"  round {round_}{' (warm-up)' if round_ == 0 else ''}: load {os.getloadavg()[0]:.2f}")
    return samples


def _spread(values: list[float]) -> dict:
    return {"median": statistics.median(values), "min": min(values), "max": max(values), "samples": values}


def summarise(samples: dict, trees: list[str]) -> dict:
    """Per tree and command: median/min/max of wall, CPU, peak MiB (and score seconds); per command
    the median of the per-round wall and peak ratios of the first tree to the second."""
    out: dict = {"trees": {}, "ratios": {}}
    for tree, by_name in samples.items():
        out["trees"][tree] = {}
        for name, runs in by_name.items():
            row = {k: _spread([getattr(s, k) for s in runs]) for k in ("wall_s", "cpu_s", "peak_mib", "load")}
            if runs and runs[0].score_s is not None:
                row["score_s"] = _spread([s.score_s for s in runs])
            out["trees"][tree][name] = row
    if len(trees) == 2:
        a, b = trees
        for name in samples[a]:
            pairs = list(zip(samples[a][name], samples[b][name]))
            out["ratios"][name] = {"wall": statistics.median(x.wall_s / y.wall_s for x, y in pairs),
                                   "peak": statistics.median(x.peak_mib / y.peak_mib for x, y in pairs)}
    return out


def _cell(row: dict, key: str, fmt: str) -> str:
    s = row[key]
    return f"{s['median']:{fmt}} ({s['min']:{fmt}}–{s['max']:{fmt}})"


def markdown(summary: dict, trees: dict[str, Path], repeats: int) -> str:
    names = list(trees)
    base = summary["trees"]["-"][BASELINE]
    lines = [f"# bench start: whole commands as processes ({repeats} alternating rounds after a warm-up)", "",
             f"Trees: {', '.join(f'`{n}` = {p}' for n, p in trees.items())}. Cells: median (min–max). "
             f"Load (1 min) during the samples: median {base['load']['median']:.2f} "
             f"({base['load']['min']:.2f}–{base['load']['max']:.2f}).", "",
             f"Floor, `{BASELINE}`: {_cell(base, 'wall_s', '.3f')} s wall, {_cell(base, 'peak_mib', '.0f')} MiB.", ""]
    head = "| command | " + " | ".join(f"{n}: wall s | {n}: CPU s | {n}: peak MiB" for n in names)
    head += " | wall ratio | peak ratio | goal |" if len(names) == 2 else " | goal |"
    lines += [head, "|" + "---|" * (head.count("|") - 1)]
    for name, (_, goal_s, goal_mib) in COMMANDS.items():
        if name not in summary["trees"][names[0]]:
            continue
        cells = []
        for n in names:
            row = summary["trees"][n][name]
            cells += [_cell(row, "wall_s", ".2f"), _cell(row, "cpu_s", ".2f"), _cell(row, "peak_mib", ".0f")]
        if len(names) == 2:
            r = summary["ratios"][name]
            cells += [f"{r['wall']:.2f}", f"{r['peak']:.2f}"]
        first = summary["trees"][names[0]][name]
        goal = []
        if goal_s is not None:
            goal.append(f"≤ {goal_s:g} s: {'met' if first['wall_s']['median'] <= goal_s else 'missed'}")
        if goal_mib is not None:
            goal.append(f"≤ {goal_mib:g} MiB: {'met' if first['peak_mib']['median'] <= goal_mib else 'missed'}")
        cells.append("; ".join(goal) or "–")
        lines.append(f"| `{name}` | " + " | ".join(cells) + " |")
    reading = "harness prune bonsai-7k --reading v1"
    if reading in summary["trees"][names[0]]:
        lines += ["", "The `score` stage as the prune command reports it (median s), default reading vs v1:"]
        for n in names:
            d, v = summary["trees"][n]["harness prune bonsai-7k"], summary["trees"][n][reading]
            lines.append(f"* `{n}`: default {d['score_s']['median']:.3f}, v1 {v['score_s']['median']:.3f} "
                         f"(ratio {d['score_s']['median'] / v['score_s']['median']:.2f})")
    return "\n".join(lines)


def run(args) -> int:
    from harness.benchmarks._common import out_dir, write_result
    from harness.core.errors import InputError
    from harness.core.paths import REPO_ROOT

    names = args.only or list(COMMANDS)
    unknown = [n for n in names if n not in COMMANDS]
    if unknown:
        raise InputError("--only", f"unknown command {unknown[0]!r}; known: {', '.join(COMMANDS)}")
    if not 1 <= args.repeats <= 100:
        raise InputError("--repeats", f"must be 1..100, got {args.repeats}")
    trees = {"this": REPO_ROOT}
    if args.against is not None:
        other = Path(args.against).expanduser().resolve()
        if not (other / "harness" / "cli.py").is_file():
            raise InputError("--against", f"{other} is not a checkout of this project (no harness/cli.py)")
        trees["against"] = other
    folder = out_dir(args)  # created and probed before any work
    print(f"bench start: {len(names)} command(s) x {len(trees)} tree(s), {args.repeats} rounds + a warm-up")
    samples = measure(trees, names, args.repeats)
    summary = summarise(samples, list(trees))
    md = markdown(summary, trees, args.repeats)
    payload = {"trees": {k: str(v) for k, v in trees.items()}, "repeats": args.repeats,
               "commands": {n: COMMANDS[n][0] for n in names}, **summary}
    write_result(NAME, payload, md, out=folder)
    print(md)
    return 0
