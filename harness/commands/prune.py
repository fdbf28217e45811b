"""`harness prune IN OUT (--ratio R | --keep K)`: score every splat, drop the lowest, write a `.ply`.

The output is the input minus rows (every kept property, extras and header comments included,
unchanged), written atomically: a failure leaves no partial file, and an output that is the input
is refused. Removes exactly ``round(R·N)`` splats (``--keep K`` is ``R = 1 − K``), ties by index
(:mod:`methods.targeting`). Prints splats before/after, τ (the score at the cut) and seconds per
stage; ``--json`` prints the same as one JSON object.

Pruner parameters: ``--param NAME=VALUE`` (repeatable), or the flag generated for every parameter
of a registered pruner (``--voxel 0.02``, ``--radius-voxels 4``; see ``harness methods``), checked
by the pruner's :class:`harness.core.params.Params` before anything is read. ``--cameras FILE``
gives training views: required by camera-aware pruners (LightGSPrune, ConfSplatPrune) and used by
BetaDescPrune's optional view-aware edge evidence when ``--view-weight`` > 0.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

from harness.commands import help_text
from harness.core import ratios
from harness.core.errors import InputError

NAME = "prune"
HELP = "prune a splat scene to a ratio with BetaDescPrune (or any registered pruner) and write a .ply"
_OWN = {"input", "output", "ratio", "keep", "method", "seed", "scores", "json", "cameras", "param", "device"}


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def add_arguments(parser) -> None:
    from methods.registry import list_pruners

    parser.add_argument("input", help="scene file (.ply, .splat, SOG) or a registered scene name")
    parser.add_argument("output", help="pruned scene, INRIA .ply")
    amount = parser.add_mutually_exclusive_group(required=True)
    amount.add_argument("--ratio", type=float, help="fraction of splats to remove, in [0, 1]")
    amount.add_argument("--keep", type=float, help="fraction of splats to keep, in [0, 1]")
    parser.add_argument("--method", default="betadesc", help="pruner name (default betadesc; see `harness methods`)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="a pruner parameter (repeatable); every parameter also has its own flag below")
    parser.add_argument("--cameras", metavar="FILE", help="training views (cameras.json, transforms.json, COLMAP, "
                        "or a PLY with camera comments) for camera-aware pruners and the view-aware evidence")
    parser.add_argument("--seed", type=int, default=0, help="seed for stochastic pruners (default 0)")
    parser.add_argument("--device", default="cpu", help="torch device of camera-aware pruners (default cpu)")
    parser.add_argument("--scores", metavar="FILE.npy", help="also save the float64 scores here")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    group = parser.add_argument_group("pruner parameters (generated from the registry; see `harness methods`)")
    seen: dict[str, list[str]] = {}
    specs = {}
    for pruner in list_pruners():
        for p in pruner.params.specs():
            seen.setdefault(p.name, []).append(pruner.name)
            specs.setdefault(p.name, p)
    for name, methods in seen.items():
        if name in _OWN:
            continue
        p = specs[name]
        group.add_argument(_flag(name), dest=f"param__{name}", metavar="V", default=None,
                           help=help_text(f"{p.doc} ({p.describe()}; default {p.default}) [{', '.join(methods)}]"))


def _given_params(args) -> dict[str, tuple[str, str]]:
    """name -> (text, where it came from) of every parameter given on the command line."""
    out: dict[str, tuple[str, str]] = {}
    for item in args.param:
        name, sep, text = item.partition("=")
        if not sep or not name.strip():
            raise InputError("--param", f"expected NAME=VALUE, got {item!r}")
        out[name.strip().replace("-", "_")] = (text, f"--param {name.strip()}")
    for key, text in vars(args).items():
        if key.startswith("param__") and text is not None:
            name = key[len("param__"):]
            if name in out:
                raise InputError(_flag(name), "given twice (as a flag and with --param)")
            out[name] = (text, _flag(name))
    return out


def resolve(args, spec):
    """The pruner's resolved parameters, or an InputError naming the flag."""
    from harness.core.params import ParamError

    given = _given_params(args)
    try:
        return spec.params.parse_text({k: text for k, (text, _) in given.items()})
    except ParamError as err:
        where = given[err.key][1] if err.key in given else "--param"
        raise InputError(where, f"method {spec.name!r}: {err.problem}") from None


def _check_paths(args) -> float:
    """The pruning ratio; every output path checked before any work, so a bad one leaves nothing."""
    from harness.io.datasets import resolve_scene

    value, flag = (args.ratio, "--ratio") if args.ratio is not None else (args.keep, "--keep")
    try:
        ratio = ratios.canonical(value) if args.ratio is not None else ratios.from_keep(value)
    except ValueError:
        raise InputError(flag, f"must be a number in [0, 1], got {value}") from None
    out = Path(args.output)
    if out.suffix.lower() != ".ply":
        raise InputError(out, "the pruned scene is written as INRIA .ply; give an output ending in .ply")
    if args.scores is not None and Path(args.scores).suffix.lower() != ".npy":
        raise InputError(args.scores, "scores are saved as .npy; give a path ending in .npy")
    inputs = [resolve_scene(args.input)] + ([Path(args.cameras)] if args.cameras else [])
    outputs = [out] + ([Path(args.scores)] if args.scores is not None else [])
    from harness.io.files import probe_writable, sweep_stale_temps

    for path in outputs:
        if not path.parent.is_dir():
            raise InputError(path, "output folder does not exist")
        if path.is_dir():
            raise InputError(path, "is a folder; give a file name")
        if path.exists() and not path.is_file():
            raise InputError(path, "exists and is not a regular file")
        probe_writable(path.parent, path)  # read-only, /proc ...: refused before any work
        sweep_stale_temps(path.parent)
        for src in inputs:
            if path.resolve() == src.resolve() or (src.is_dir() and src.resolve() in path.resolve().parents):
                raise InputError(path, f"would overwrite the input {src}; choose another output")
    if args.scores is not None and Path(args.scores).resolve() == out.resolve():
        raise InputError(args.scores, "the scores file and the pruned scene are the same path")
    return ratio


def _cameras(args, spec, params):
    if not args.cameras:
        if "cameras" in spec.needs:
            raise InputError("--method", f"{spec.name!r} needs training cameras; give them with --cameras FILE")
        return None
    if not spec.wants_cameras(params):
        hint = " (enable its view-aware evidence with --view-weight > 0)" if "view_weight" in params.names() else ""
        raise InputError("--cameras", f"{spec.name!r} does not use cameras with these parameters{hint}")
    from harness.io.cameras import load_cameras

    return load_cameras(args.cameras)


def run(args) -> int:
    from harness.core.timing import record_stages
    from harness.io.files import atomic_write_npy
    from harness.io.scenes import load_scene, write_scene
    from methods import PruneContext, get_pruner, select_by_ratio

    try:
        spec = get_pruner(args.method)
    except KeyError as err:
        raise InputError("--method", str(err.args[0])) from None
    from harness.core.devices import check_device

    params = resolve(args, spec)
    ratio = _check_paths(args)
    check_device(args.device, "--device")
    cameras = _cameras(args, spec, params)

    seconds: dict[str, float] = {}
    t0 = time.perf_counter()
    scene = load_scene(args.input)
    seconds["read"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    with record_stages() as stages:
        try:
            scores = spec.score(scene, PruneContext(params=params, seed=args.seed, cameras=cameras,
                                                    device=args.device))
        except ValueError as err:  # a value the method rejects only once it sees the scene
            raise InputError("--method", f"{spec.name}: {err}") from None
    seconds["score"] = time.perf_counter() - t0
    seconds.update({f"score.{k}": v for k, v in stages.items()})

    t0 = time.perf_counter()
    selection = select_by_ratio(scores, ratio)
    seconds["select"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    existed = Path(args.output).exists()
    write_scene(scene.subset(selection.keep), args.output)  # the input's header comments travel with it
    if args.scores is not None:
        try:
            atomic_write_npy(args.scores, scores)
        except OSError as err:  # the scene must not stay behind as if the command had succeeded
            if not existed:
                Path(args.output).unlink(missing_ok=True)
            raise InputError(args.scores, f"cannot write: {err.strerror or err}") from None
    seconds["write"] = time.perf_counter() - t0

    report = {"method": spec.name, "params": params.to_dict(), "splats_in": len(scene),
              "splats_out": selection.kept, "removed": selection.removed,
              "tau": selection.tau if math.isfinite(selection.tau) else None,  # None: nothing removed
              "tau_quantile": selection.tau_quantile,
              "seconds": seconds}
    if args.json:
        from harness.core.jsonout import dumps

        print(dumps(report))
    else:
        print(f"{spec.name}: {len(scene):,} -> {selection.kept:,} splats "
              f"(removed {selection.removed:,}, tau = {selection.tau:.6g})")
        print("  " + ", ".join(f"{k} {v:.3f} s" for k, v in seconds.items()))
    return 0

