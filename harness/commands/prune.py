"""`harness prune IN OUT (--ratio R | --keep K)`: score every splat, drop the lowest, write OUT.

The output is the input minus rows, written atomically in the format OUT's name asks for
(:mod:`harness.io.writers`: ``.ply`` keeps every property, extras and header comments unchanged;
``.compressed.ply``, ``.splat``, ``.spz`` are lossy); a failure leaves no partial file, and an output
that is the input is refused. Removes exactly ``round(R·N)`` splats (``--keep K`` is ``R = 1 − K``),
ties by index (:mod:`methods.targeting`). Prints splats before/after, τ (the score at the cut;
"none" when nothing is removed) and seconds per stage; ``--json`` prints the same as one JSON object.

``--ratio 0`` (``--keep 1``) removes nothing, so nothing is scored (unless ``--scores`` asks for the
scores): the command is then ``harness convert IN OUT``, and says so; the method's parameters are
still checked.

Pruner parameters: ``--param NAME=VALUE`` (repeatable), or the flag generated for every parameter
of the chosen pruner (``--method``, default betadesc: ``--voxel 0.02``, ``--radius-voxels 4``;
``harness prune --method NAME --help`` lists another pruner's, ``harness methods`` all of them),
checked by the pruner's :class:`harness.core.params.Params` before anything is read. A flag of
another pruner is refused at parsing with the pruners it belongs to. ``--cameras FILE`` gives
training views: required by camera-aware pruners (LightGSPrune, ConfSplatPrune) and used by
BetaDescPrune's optional view-aware edge evidence when ``--view-weight`` > 0.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from harness.commands import help_text
from harness.core import ratios
from harness.core.errors import InputError

NAME = "prune"
HELP = "prune a splat scene to a ratio with BetaDescPrune (or any registered pruner) and write it (.ply, .spz ...)"
DEFAULT_METHOD = "betadesc"
_OWN = {"input", "output", "ratio", "keep", "method", "seed", "scores", "json", "cameras", "param", "device"}


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def _method_in(argv) -> str:
    """The ``--method`` value among the command's arguments (the last one wins, as in argparse)."""
    method = DEFAULT_METHOD
    for i, word in enumerate(argv):
        if word == "--method" and i + 1 < len(argv):
            method = argv[i + 1]
        elif word.startswith("--method="):
            method = word.split("=", 1)[1]
    return method


def add_arguments(parser, argv=()) -> None:
    from harness.io.writers import endings
    from methods.registry import list_pruners

    parser.add_argument("input", help="scene file (.ply, .compressed.ply, .spz, .ksplat, .splat, SOG) or a scene name")
    parser.add_argument("output", help=f"the pruned scene; its name picks the format: {', '.join(endings())}")
    amount = parser.add_mutually_exclusive_group(required=True)
    amount.add_argument("--ratio", type=float, help="fraction of splats to remove, in [0, 1] (0: nothing is scored)")
    amount.add_argument("--keep", type=float, help="fraction of splats to keep, in [0, 1]")
    parser.add_argument("--method", default=DEFAULT_METHOD,
                        help=f"pruner name (default {DEFAULT_METHOD}; see `harness methods`)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="a pruner parameter (repeatable); each also has its own flag below")
    parser.add_argument("--cameras", metavar="FILE", help="training views (cameras.json, transforms.json, COLMAP, "
                        "or a PLY with camera comments) for camera-aware pruners and the view-aware evidence")
    parser.add_argument("--seed", type=int, default=0, help="seed for stochastic pruners (default 0)")
    parser.add_argument("--device", default="cpu", help="torch device of camera-aware pruners (default cpu)")
    parser.add_argument("--scores", metavar="FILE.npy", help="also save the float64 scores here")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    pruners = {p.name: p for p in list_pruners()}
    method = _method_in(argv)
    chosen = [pruners[method]] if method in pruners else list(pruners.values())  # unknown: run() says so
    title = (f"{method} parameters ({pruners[method].label}; `harness prune --method NAME --help` shows another "
             "pruner's)" if method in pruners else "pruner parameters (every pruner's)")
    group = parser.add_argument_group(title)
    owners: dict[str, list[str]] = {}
    for spec in pruners.values():
        for p in spec.params.specs():
            owners.setdefault(p.name, []).append(spec.name)
    added = set()
    for spec in chosen:
        for p in spec.params.specs():
            if p.name in _OWN or p.name in added:
                continue
            added.add(p.name)
            group.add_argument(_flag(p.name), dest=f"param__{p.name}", metavar="V", default=None,
                               help=help_text(f"{p.doc} ({p.describe()}; default {p.default})"))
    hints = getattr(parser, "hints", None)
    if hints is not None:
        for name, who in owners.items():
            if name not in added and name not in _OWN:
                hints[_flag(name)] = f"a parameter of {', '.join(who)}, not of {method} (choose it with --method)"


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
    from harness.commands._outputs import check_outputs
    from harness.io.datasets import resolve_scene
    from harness.io.writers import writer_for

    value, flag = (args.ratio, "--ratio") if args.ratio is not None else (args.keep, "--keep")
    try:
        ratio = ratios.canonical(value) if args.ratio is not None else ratios.from_keep(value)
    except ValueError:
        raise InputError(flag, f"must be a number in [0, 1], got {value}") from None
    out = Path(args.output)
    writer_for(out)  # the format from the name, refused before any work
    if args.scores is not None and Path(args.scores).suffix.lower() != ".npy":
        raise InputError(args.scores, "scores are saved as .npy; give a path ending in .npy")
    inputs = [resolve_scene(args.input)] + ([Path(args.cameras)] if args.cameras else [])
    check_outputs([out] + ([Path(args.scores)] if args.scores is not None else []), inputs)
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

    scores = None
    convert_only = ratio == 0.0 and args.scores is None  # nothing to remove: nothing to score
    if not convert_only:
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
    selection = select_by_ratio(scores if scores is not None else np.zeros(len(scene)), ratio)
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

    tau = selection.tau if math.isfinite(selection.tau) else None  # None: nothing removed
    report = {"method": spec.name, "params": params.to_dict(), "splats_in": len(scene),
              "splats_out": selection.kept, "removed": selection.removed, "scored": scores is not None,
              "tau": tau, "tau_quantile": selection.tau_quantile, "seconds": seconds}
    if args.json:
        from harness.core.jsonout import dumps

        print(dumps(report))
    else:
        print(f"{spec.name}: {len(scene):,} -> {selection.kept:,} splats "
              f"(removed {selection.removed:,}, tau = {'none' if tau is None else f'{tau:.6g}'})")
        if convert_only:
            print(f"  ratio 0: nothing removed and nothing scored; the same as `harness convert {args.input} "
                  f"{args.output}`")
        print("  " + ", ".join(f"{k} {v:.3f} s" for k, v in seconds.items()))
    return 0
