"""`harness diagnose SCENE [--method M[:k=v,...]] [--ratio R] [--json]`: render-free diagnostics.

Per pruner: Spearman's ρ of each per-splat quantity (BetaDesc: s, ℓ, o, u, w, A, B, score; others:
the score) with LightGaussian's global significance over the scene's default-rig training views,
and at ratio R the shares of significance and of opacity·volume removed and the fraction of removed
splats that come from voxels losing > 90 % of their splats (:mod:`methods.diagnose`).

``--method`` is repeatable; parameters follow a colon (``betadesc:reading=v1,o_norm=rank``).
``random``, ``opacity`` and ``lightgs`` are added as references unless ``--no-references``; ``lightgs``
without parameters *is* the significance pass (ρ = 1, the least significance a pruner can remove).
"""

from __future__ import annotations

from harness.core import jsonout
from harness.core.errors import InputError

NAME = "diagnose"
HELP = "render-free diagnostics of a pruner: correlation with LightGS significance, what a ratio removes"
REFERENCES = ("random", "opacity", "lightgs")
RIG_METHODS = ("virtual-rig", "betadesc-vr")


def add_arguments(parser) -> None:
    parser.add_argument("scene", help="scene file or registered scene name")
    parser.add_argument("--method", action="append", default=[], metavar="M[:k=v,...]",
                        help="pruner (repeatable; default betadesc), parameters after a colon")
    parser.add_argument("--ratio", type=float, default=0.3, help="pruning ratio (default 0.3)")
    parser.add_argument("--lod", type=int, default=None, help="SOG level of detail")
    parser.add_argument("--n-train", type=int, default=16, help="rig training views for LightGS (default 16)")
    parser.add_argument("--n-test", type=int, default=12, help="rig held-out views (not used; they fix the rig)")
    parser.add_argument("--longest-side", type=int, default=384, help="rig view size (px, default 384)")
    parser.add_argument("--significance-side", type=int, default=512,
                        help="render size of the significance pass (px, default 512 = lightgs default)")
    parser.add_argument(
        "--voxel",
        type=float,
        default=None,
        help="voxel (fraction of the diagonal) of the region measure (default: the method's, else 0.01)",
    )
    parser.add_argument("--no-references", action="store_true", help="do not add random, opacity, lightgs")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--picture", default=None, metavar="PNG",
                        help="virtual-rig / betadesc-vr: where to draw the rig over the scene (default "
                        "virtual-rig-<scene>.png in the current folder)")
    parser.add_argument("--no-picture", action="store_true", help="do not draw the virtual rig")


def parse_method(text: str):
    """(name, params as text) of ``M[:k=v,...]``, parameters checked by the pruner."""
    from harness.core.params import ParamError
    from methods.registry import get_pruner

    name, _, rest = text.partition(":")
    try:
        spec = get_pruner(name.strip())
    except KeyError as err:
        raise InputError("--method", str(err.args[0])) from None
    given = {}
    for item in filter(None, (x.strip() for x in rest.split(","))):
        k, sep, v = item.partition("=")
        if not sep:
            raise InputError("--method", f"expected k=v in {text!r}, got {item!r}")
        given[k.strip().replace("-", "_")] = v.strip()
    try:
        return spec.name, spec.params.parse_text(given).to_dict(), given
    except ParamError as err:
        raise InputError("--method", f"{spec.name}: {err}") from None


def run(args) -> int:
    import math

    from harness.core.extent import check_extent
    from harness.io.scenes import load_scene
    from harness.views.rigs import training_views
    from methods import diagnose as dg

    if not (math.isfinite(args.ratio) and 0.0 <= args.ratio <= 1.0):
        raise InputError("--ratio", f"must be in [0, 1], got {args.ratio}")
    methods = [parse_method(m) for m in (args.method or ["betadesc"])]
    if not args.no_picture and any(name in RIG_METHODS for name, _, _ in methods):
        check_picture_path(args)
    if not args.no_references:
        methods += [parse_method(m) for m in REFERENCES if m not in {x[0] for x in methods}]
    sig_params = parse_method(f"lightgs:train_longest_side={args.significance_side}")[1]
    scene = load_scene(args.scene, lod=args.lod)
    if len(scene) == 0:
        raise InputError(args.scene, "the scene has no splats")
    check_extent(scene, args.scene)
    cams = training_views(args.scene, scene, n_train=args.n_train, n_test=args.n_test,
                             longest_side=args.longest_side, seed=args.seed)
    if not cams:
        raise InputError("--n-train", "the rig has no training views to compute LightGS significance from")
    sig = dg.lightgs_significance(scene, cams, longest_side=args.significance_side, device=args.device)
    if not sig.sum() > 0:  # every share of it would be 0/0
        raise InputError(args.scene, f"no training view sees a splat (LightGS significance is 0 over all {len(cams)} "
                                     "views): there is nothing to diagnose against")
    out = []
    for name, params, given in methods:
        try:
            same = name == "lightgs" and (params == sig_params or not given)
            d = dg.diagnose(scene, name, sig_params if same else params, args.ratio, sig, cameras=cams,
                            voxel=args.voxel, seed=args.seed, device=args.device, score=sig if same else None)
        except ValueError as err:
            raise InputError("--method", f"{name}: {err}") from None
        d.label = name + (":" + ",".join(f"{k}={v}" for k, v in given.items()) if given else "")
        out.append(d)
    rigs = [] if args.no_picture else [draw_virtual_rig(scene, args, name, params) for name, params, _ in methods
                                       if name in RIG_METHODS][:1]
    if args.json:
        print(jsonout.dumps({"scene": args.scene, "splats": len(scene), "ratio": args.ratio,
                             "train_views": len(cams), "diagnoses": [d.to_dict() for d in out],
                             "virtual_rig": rigs[0] if rigs else None}))
    else:
        print(dg.format_text(args.scene, len(scene), out))
        for r in rigs:
            print("\nvirtual rig\n  " + r["text"].replace("\n", "\n  ") + f"\n  picture: {r['picture']}")
    return 0


def check_picture_path(args) -> None:
    """Refuse, before any work, a picture path that is not a .png or whose folder takes no file."""
    from pathlib import Path

    from harness.io.files import probe_writable

    stem = Path(str(args.scene)).name.split(".")[0]
    args.picture = args.picture or f"virtual-rig-{stem}.png"
    if Path(args.picture).suffix.lower() != ".png":
        raise InputError("--picture", f"the rig picture is a PNG: give a path ending in .png, got {args.picture!r}")
    probe_writable(Path(args.picture).resolve().parent)


def draw_virtual_rig(scene, args, name: str, params: dict) -> dict:
    """Draw the virtual rig of ``name`` (its rig parameters from ``params``) over ``scene``: the PNG
    path, what the rig found, and where every camera stands."""
    from pathlib import Path

    import numpy as np

    from harness.views.rig_picture import draw_rig
    from methods.virtualrig import VirtualRigParams, rig_report

    fields = VirtualRigParams.__dataclass_fields__
    p = VirtualRigParams(**{k: v for k, v in params.items() if k in fields})
    try:
        shape, ground, cams, text = rig_report(scene, p)
    except ValueError as err:
        raise InputError("--method", f"{name}: {err}") from None
    stem = Path(str(args.scene)).name.split(".")[0]
    path = Path(args.picture)
    reach = max([shape.radius] + [float(np.linalg.norm(c.center - shape.center)) for c in cams])
    up = None if ground is None else ground.up
    draw_rig(scene, cams, path, center=shape.center, radius=reach * 1.02, up=up, title=f"{stem}: {name}")
    return {"picture": str(path), "text": text, "cameras": [
        {"name": c.name, "position": np.round(c.center, 6).tolist(), "forward": np.round(c.forward, 6).tolist()}
        for c in cams]}
