"""`harness prune IN OUT (--ratio R | --keep K)`: score every splat, drop the lowest, write OUT.

The output is the input minus rows, written atomically in the format OUT's name asks for
(:mod:`harness.io.writers`: ``.ply`` keeps every property, extras and header comments unchanged;
``.compressed.ply``, ``.splat``, ``.spz`` and SOG ``.sog``/``meta.json`` are lossy); a failure leaves
no partial file, and an output that is the input is refused. Removes exactly ``round(R·N)`` splats
(``--keep K`` is ``R = 1 − K``), ties by index (:mod:`methods.targeting`). Prints splats
before/after, τ (the score at the cut; "none" when nothing is removed) and seconds per stage;
``--json`` prints the same as one JSON object.

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

The work is :func:`harness.api.prune` (``harness.prune`` in Python): this module turns the flags
into its arguments, checks the outputs first, writes the kept splats and prints the report.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

from harness.commands import help_text
from harness.core.errors import InputError

NAME = "prune"
HELP = "prune a splat scene to a ratio with BetaDescPrune (or any registered pruner) and write it (.ply, .spz ...)"
_OWN = {"input", "output", "ratio", "keep", "method", "seed", "scores", "json", "cameras", "param", "device"}


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def _method_in(argv) -> str:
    """The ``--method`` value among the command's arguments (the last one wins, as in argparse)."""
    from harness.api.scenes import DEFAULT_METHOD

    method = DEFAULT_METHOD
    for i, word in enumerate(argv):
        if word == "--method" and i + 1 < len(argv):
            method = argv[i + 1]
        elif word.startswith("--method="):
            method = word.split("=", 1)[1]
    return method


def add_arguments(parser, argv=()) -> None:
    from harness.api.scenes import DEFAULT_METHOD
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


def _check_outputs(args) -> None:
    """Every output path checked before any work, so a bad one leaves nothing."""
    from harness.api.scenes import check_outputs
    from harness.io.datasets import resolve_scene
    from harness.io.writers import writer_for

    out = Path(args.output)
    files = writer_for(out).files(out)  # the format from the name, refused before any work
    if args.scores is not None and Path(args.scores).suffix.lower() != ".npy":
        raise InputError(args.scores, "scores are saved as .npy; give a path ending in .npy")
    inputs = [resolve_scene(args.input)] + ([Path(args.cameras)] if args.cameras else [])
    check_outputs(files + ([Path(args.scores)] if args.scores is not None else []), inputs)
    if args.scores is not None and Path(args.scores).resolve() == out.resolve():
        raise InputError(args.scores, "the scores file and the pruned scene are the same path")


#: how this command names the API's arguments (:func:`harness.core.errors.naming`)
FLAGS = {"ratio": "--ratio", "keep": "--keep", "method": "--method", "cameras": "--cameras", "device": "--device"}


def run(args) -> int:
    from harness import api
    from harness.core.errors import naming
    from harness.io.files import atomic_write_npy
    from harness.io.scenes import write_scene

    with naming(FLAGS):
        spec, _ = api.scenes.pruner(args.method, {}, announce_advice=False)  # an unknown --method before its parameters
    params = resolve(args, spec).to_dict()  # text -> values, errors naming the flags
    _check_outputs(args)
    with naming(FLAGS):
        pruned = api.prune(args.input, args.ratio, keep=args.keep, method=spec.name, cameras=args.cameras,
                           seed=args.seed, device=args.device, **params)
        seconds, scores = dict(pruned.seconds), pruned.scores
        if scores is None and args.scores is not None:  # ratio 0 scores nothing unless --scores asks
            t0 = time.perf_counter()
            scores = api.score(pruned.scene, spec.name, cameras=args.cameras, seed=args.seed, device=args.device,
                               **params)  # pruned.scene: every splat, nothing was removed
            seconds = {"read": seconds["read"], "score": time.perf_counter() - t0, "select": seconds["select"]}

    t0 = time.perf_counter()
    existed = Path(args.output).exists()
    write_scene(pruned.scene, args.output)  # the input's header comments travel with it
    if args.scores is not None:
        try:
            atomic_write_npy(args.scores, scores)
        except OSError as err:  # the scene must not stay behind as if the command had succeeded
            if not existed:
                Path(args.output).unlink(missing_ok=True)
            raise InputError(args.scores, f"cannot write: {err.strerror or err}") from None
    seconds["write"] = time.perf_counter() - t0

    tau = pruned.tau if math.isfinite(pruned.tau) else None  # None: nothing removed
    splats_in = len(pruned.mask)
    report = {"method": spec.name, "params": pruned.params, "splats_in": splats_in,
              "splats_out": pruned.kept, "removed": pruned.removed, "scored": scores is not None,
              "tau": tau, "tau_quantile": pruned.removed / splats_in if splats_in else 0.0, "seconds": seconds}
    if args.json:
        from harness.core.jsonout import dumps

        print(dumps(report))
    else:
        print(f"{spec.name}: {splats_in:,} -> {pruned.kept:,} splats "
              f"(removed {pruned.removed:,}, tau = {'none' if tau is None else f'{tau:.6g}'})")
        if scores is None:
            print(f"  ratio 0: nothing removed and nothing scored; the same as `harness convert {args.input} "
                  f"{args.output}`")
        print("  " + ", ".join(f"{k} {v:.3f} s" for k, v in seconds.items()))
    return 0
