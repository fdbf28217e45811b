"""`harness prune IN OUT (--ratio R | --keep K)`: score every splat, drop the lowest, write a `.ply`.

The output is the input minus rows (every kept property, extras included, unchanged), written
atomically: a failure leaves no partial file. Removes exactly ``round(R·N)`` splats (``--keep K``
is ``R = 1 − K``), ties by index (:mod:`methods.targeting`). Prints splats before/after, τ (the
score at the cut) and seconds per stage; ``--json`` prints the same as one JSON object.
"""

from __future__ import annotations

import json
import math
import time
from contextlib import nullcontext
from pathlib import Path

from harness.core.errors import InputError
from harness.io.files import atomic_write_npy

NAME = "prune"
HELP = "prune a splat scene to a ratio with BetaDescPrune (or any registered pruner) and write a .ply"


def add_arguments(parser) -> None:
    parser.add_argument("input", help="scene file (.ply, .splat, SOG) or a registered scene name")
    parser.add_argument("output", help="pruned scene, INRIA .ply")
    amount = parser.add_mutually_exclusive_group(required=True)
    amount.add_argument("--ratio", type=float, help="fraction of splats to remove, in [0, 1]")
    amount.add_argument("--keep", type=float, help="fraction of splats to keep, in [0, 1]")
    parser.add_argument("--method", default="betadesc", help="pruner name (default betadesc; see `harness methods`)")
    parser.add_argument("--preset", help="evidence coefficient preset (betadesc family)")
    parser.add_argument("--voxel", type=float, help="voxel edge as a fraction of the bounding-box diagonal")
    parser.add_argument("--score", help="score kind: ucb, lcb, quantile or literal (Beta variants)")
    parser.add_argument("--gamma", type=float, help="uncertainty weight γ of the ucb/literal scores")
    parser.add_argument("--seed", type=int, default=0, help="seed for stochastic pruners (default 0)")
    parser.add_argument("--scores", metavar="FILE.npy", help="also save the float64 scores here")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def _params(args, spec) -> dict:
    given = {"preset": args.preset, "voxel": args.voxel, "score": args.score, "gamma": args.gamma}
    params = {k: v for k, v in given.items() if v is not None}
    unknown = sorted(set(params) - set(spec.params))
    if unknown:
        raise InputError(f"--{unknown[0]}", f"method {spec.name!r} has no parameter {unknown[0]!r}")
    return params


def _check_args(args) -> float:
    value, flag = (args.ratio, "--ratio") if args.ratio is not None else (args.keep, "--keep")
    if not (math.isfinite(value) and 0.0 <= value <= 1.0):
        raise InputError(flag, f"must be a number in [0, 1], got {value}")
    out = Path(args.output)
    if out.suffix.lower() != ".ply":
        raise InputError(out, "the pruned scene is written as INRIA .ply; give an output ending in .ply")
    if args.scores is not None and Path(args.scores).suffix.lower() != ".npy":
        raise InputError(args.scores, "scores are saved as .npy; give a path ending in .npy")
    for path in (out, args.scores):  # checked before any work, so a bad path leaves no output
        if path is not None and not Path(path).parent.is_dir():
            raise InputError(path, "output folder does not exist")
    return value if args.ratio is not None else 1.0 - value


def _ply_comments(source) -> list[str]:
    """Header comments of a .ply input (kept in the output: pruned = input minus rows); none otherwise."""
    from harness.io.datasets import resolve_scene
    from harness.io.ply import read_ply_header

    path = resolve_scene(source)
    return read_ply_header(path).comments if path.suffix.lower() == ".ply" else []


def run(args) -> int:
    from harness.io.scenes import load_scene, write_scene
    from methods import PruneContext, get_pruner, select_by_ratio

    ratio = _check_args(args)
    try:
        spec = get_pruner(args.method)
    except KeyError as err:
        raise InputError("--method", str(err.args[0])) from None
    params = _params(args, spec)
    try:
        spec.resolve_params(params)
    except KeyError as err:
        raise InputError("--method", str(err.args[0])) from None
    if spec.needs:
        raise InputError("--method", f"{spec.name!r} needs {', '.join(sorted(spec.needs))}; "
                                     "`harness prune` runs camera-agnostic pruners only")

    seconds: dict[str, float] = {}
    t0 = time.perf_counter()
    scene = load_scene(args.input)
    seconds["read"] = time.perf_counter() - t0

    recorder = nullcontext({})
    if spec.fn.__module__.startswith("methods.betadesc"):
        from methods.betadesc.pipeline import record_stages

        recorder = record_stages()
    t0 = time.perf_counter()
    with recorder as stages:
        try:
            scores = spec.score(scene, PruneContext(params=params, seed=args.seed))
        except ValueError as err:  # a parameter value the method rejects
            raise InputError("--method", f"{spec.name}: {err}") from None
    seconds["score"] = time.perf_counter() - t0
    seconds.update({f"score.{k}": v for k, v in stages.items()})

    t0 = time.perf_counter()
    selection = select_by_ratio(scores, ratio)
    seconds["select"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    write_scene(scene.subset(selection.keep), args.output, comments=_ply_comments(args.input))
    if args.scores is not None:
        atomic_write_npy(args.scores, scores)
    seconds["write"] = time.perf_counter() - t0

    report = {"method": spec.name, "splats_in": len(scene), "splats_out": selection.kept,
              "removed": selection.removed,
              "tau": selection.tau if math.isfinite(selection.tau) else None,  # None: nothing removed
              "tau_quantile": selection.tau_quantile,
              "seconds": seconds}
    if args.json:
        print(json.dumps(report, default=float))
    else:
        print(f"{spec.name}: {len(scene):,} -> {selection.kept:,} splats "
              f"(removed {selection.removed:,}, tau = {selection.tau:.6g})")
        print("  " + ", ".join(f"{k} {v:.3f} s" for k, v in seconds.items()))
    return 0
