"""`harness render SCENE [--cameras FILE | --rig NAME] --out DIR`: render views of a scene.

Writes into DIR (created if needed; every file written atomically, one view at a time — a render
holds one image in memory, not all of them):

* ``NNN_<view name>.png`` (image clamped to [0, 1], 8-bit, no gamma: the linear render as-is) or
  ``.npy`` (float32 H×W×3, linear, unclamped: exactly what the renderer returned);
* ``contact_sheet.png`` (all rendered views, labelled with their coverage, see
  :mod:`harness.views.contact_sheet`), ``coverage.json`` (per view) and ``cameras.json`` (the views,
  3DGS format, so a render can be repeated with ``--cameras``).

**Predictable views** (issue 23: ``render luigi30.ply --rig default`` picked 1024×768 where
``render luigi`` picked 1024×1024 under the same view names, and ``compare`` failed). The rule:
views come from the scene's content and the flags, never from its file name, and **image sizes
from the flags alone**, so renders of any two scenes made with the same flags have the same sizes:

* ``--cameras FILE`` reads a camera file (:mod:`harness.io.cameras`) and renders **every** camera in
  it, as given (sizes as stored unless ``--longest-side``); ``--split test|train`` picks the 3DGS
  ``llffhold`` split instead (test = every 8th view, i % 8 == 0);
* ``--rig NAME`` (orbit, room, forward, auto) builds that synthetic rig from the flags alone
  (``--up``, ``--aspect``, ``--n-train/--n-test``, ``--seed``, ``--longest-side``), fitted to the content;
* neither (or ``--rig default``): the cameras embedded in the scene's header when it has any (used
  as given, like a camera file); else a named dataset's own rig — its rig kind, up axis and
  elevations (:data:`harness.views.rigs.SCENE_RIGS`) — when the scene *is* that dataset (given by
  name, or a file of the same content) or was pruned from it (its splats' positions are a subset of
  the dataset's, checked against the datasets on this machine): the rig is then fitted to the
  dataset's own content, so ``render luigi`` and ``render luigi30.ply`` (luigi pruned by 30 %) render
  exactly the same cameras; else ``auto``.

Rigs render ``--longest-side`` px (default 1024) at ``--aspect`` (default 4/3) — a dataset's own rig
included —, and their held-out ``test`` views unless ``--split`` says otherwise. At most
:data:`harness.views.rigs.MAX_VIEWS` views per split.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from harness.core.errors import InputError
from harness.io.files import atomic_write_npy, atomic_write_text, atomic_write_with
from harness.views.rigs import ASPECT, LONGEST_SIDE, MAX_VIEWS, N_TEST, N_TRAIN, RIG_CHOICES
from renderers import RENDERERS

NAME = "render"
HELP = "render a scene from a camera file or a synthetic rig (images + contact sheet)"
LLFF_HOLD = 8
#: how this command names the API's arguments (:func:`harness.core.errors.naming`)
FLAGS = {"background": "--background", "device": "--device", "backend": "--backend"}


def add_arguments(parser) -> None:
    parser.add_argument("scene", help="scene file/folder or dataset name (bonsai-7k, playbot, ...)")
    views = parser.add_mutually_exclusive_group()
    views.add_argument("--cameras", metavar="FILE", help="camera file: cameras.json, transforms.json, "
                       "COLMAP model folder, or a PLY with camera comments; every camera is rendered as given "
                       "unless --split is passed")
    views.add_argument("--rig", choices=RIG_CHOICES, help="synthetic rig from the flags alone; `default`: the "
                       "scene's own (its embedded cameras, a dataset's rig, else auto), as without the flag")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder")
    parser.add_argument("--backend", choices=tuple(RENDERERS.names()), default="gl", help="renderer (default gl)")
    parser.add_argument("--device", default=None, help="torch device for the reference renderer")
    parser.add_argument("--format", choices=("png", "npy"), default="png", help="image format (default png)")
    parser.add_argument("--split", choices=("test", "train", "all"), default=None,
                        help="views to render: a camera file's or embedded cameras are all rendered unless this "
                             "is passed (test = every 8th, train = the others); a rig's default is test")
    parser.add_argument("--longest-side", type=int, default=None, metavar="N",
                        help=f"image size (long side; rigs default {LONGEST_SIDE}, camera files as stored)")
    parser.add_argument("--n-train", type=int, default=N_TRAIN, help=f"rig training views (default {N_TRAIN}, "
                                                                     f"at most {MAX_VIEWS})")
    parser.add_argument("--n-test", type=int, default=N_TEST, help=f"rig held-out views (default {N_TEST}, "
                                                                   f"at most {MAX_VIEWS})")
    parser.add_argument("--seed", type=int, default=0, help="rig seed (default 0)")
    parser.add_argument("--aspect", type=float, default=None,
                        help=f"rig width/height (default {ASPECT:.4g} for every rig: sizes come from the flags only)")
    parser.add_argument("--up", default=None, metavar="X,Y,Z", help="world direction drawn upwards (default 0,-1,0)")
    parser.add_argument("--background", default="0,0,0", metavar="R,G,B", help="background colour in [0, 1]")


def _triple(text: str | None, flag: str):
    if text is None:
        return None
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != 3 or not all(np.isfinite(vals)):
        raise InputError(flag, f"expected three numbers X,Y,Z, got {text!r}")
    return vals


def _split_llff(cams):
    return ([c for i, c in enumerate(cams) if i % LLFF_HOLD != 0], [c for i, c in enumerate(cams) if i % LLFF_HOLD == 0])


def _position_keys(scene) -> np.ndarray:
    """One 64-bit key per splat from the exact bits of its position (a pruned file keeps them)."""
    bits = np.ascontiguousarray(scene.means, dtype=np.float32).view(np.uint32).astype(np.uint64)
    k = bits[:, 0] * np.uint64(0x9E3779B97F4A7C15)
    k ^= bits[:, 1] * np.uint64(0xC2B2AE3D27D4EB4F) + (k >> np.uint64(29))
    k ^= bits[:, 2] * np.uint64(0x165667B19E3779F9) + (k >> np.uint64(31))
    return k


def source_dataset(arg: str, scene):
    """(dataset name, the scene its rig is fitted to, how it was recognised) or None: the named
    dataset ``scene`` is, or was pruned from (module docstring)."""
    from harness.io.datasets import SCENES, identify, scene_path
    from harness.io.scenes import load_scene

    name = identify(arg)
    if name is not None:
        return name, scene, f"the {name} dataset's own"
    keys = None
    for name in SCENES:
        path = scene_path(name)
        if not path.exists():
            continue
        data = load_scene(path)
        if len(data) < len(scene) or data.sh_degree != scene.sh_degree:
            continue
        keys = _position_keys(scene) if keys is None else keys
        if np.isin(keys, _position_keys(data)).all():
            return name, data, f"the {name} dataset's own, fitted to {name}: this scene's splats are a subset of it"
    return None


def select_views(args, scene):
    """(where the views came from, the cameras to render), per the module docstring."""
    from harness.core.cameras import MAX_SIDE
    from harness.io.cameras import embedded_cameras, load_cameras

    if args.longest_side is not None and not 1 <= args.longest_side <= MAX_SIDE:
        raise InputError("--longest-side", f"must be 1..{MAX_SIDE} pixels (the maximum render size), "
                                           f"got {args.longest_side}")
    up = _triple(args.up, "--up")
    if up is not None and not any(up):
        raise InputError("--up", "must be a non-zero direction")
    file_cams = load_cameras(args.cameras) if args.cameras else None
    if file_cams is None and args.rig in (None, "default"):
        file_cams = embedded_cameras(scene) or None
    if file_cams is not None:
        origin = args.cameras or f"{scene.meta.source or args.scene} (embedded cameras)"
        cams = [c.resized(args.longest_side) for c in file_cams] if args.longest_side else file_cams
        if args.split is None:  # used as given
            return f"{origin}, every camera", cams
        train, test = _split_llff(cams)
        selected = {"test": test, "train": train, "all": cams}[args.split]
        origin += f", {args.split} split (every {LLFF_HOLD}th view is a test view)"
    else:
        from harness.views.rigs import scene_rig

        if not 1 <= args.n_test <= MAX_VIEWS or not 0 <= args.n_train <= MAX_VIEWS:
            raise InputError("--n-test/--n-train", f"need 1..{MAX_VIEWS} test views and 0..{MAX_VIEWS} training "
                                                   f"views, got {args.n_test} and {args.n_train}")
        if args.aspect is not None and not (np.isfinite(args.aspect) and 0.1 <= args.aspect <= 10):
            raise InputError("--aspect", f"must be a width/height ratio in [0.1, 10], got {args.aspect}")
        rig = args.rig or "default"
        found = source_dataset(args.scene, scene) if rig == "default" else None
        dataset, fitted, how = found if found else (None, scene, "")
        try:
            views = scene_rig(dataset, fitted, rig, n_train=args.n_train, n_test=args.n_test, seed=args.seed,
                              longest_side=args.longest_side or LONGEST_SIDE, aspect=args.aspect or ASPECT, up=up)
        except ValueError as err:
            raise InputError(args.scene, f"cannot build a rig: {err}") from None
        origin = f"rig {views.rig}" + (f" ({how})" if how else "")
        split = args.split or "test"
        selected = {"test": views.test, "train": views.train, "all": views.all}[split]
        origin += f", {split} views"
    if not selected:
        raise InputError("--split", f"the {args.split!r} split has no views")
    return origin, selected


def _safe(name: str) -> str:
    stem = re.sub(r"[^A-Za-z0-9._-]+", "_", Path(name).with_suffix("").as_posix()).strip("._")
    return stem[:80] or "view"


def _save_image(image: np.ndarray, path: Path, fmt: str) -> None:
    if fmt == "npy":
        atomic_write_npy(path, np.asarray(image, np.float32))
    else:
        from PIL import Image

        from harness.views.contact_sheet import to_uint8

        atomic_write_with(path, lambda t: Image.fromarray(to_uint8(image)).save(t, format="PNG"))


def run(args) -> int:
    from harness.api.images import check_background, start_renderer
    from harness.core.devices import check_device
    from harness.core.errors import naming
    from harness.io.cameras import write_3dgs_cameras
    from harness.io.scenes import load_scene
    from harness.views.contact_sheet import ContactSheet

    with naming(FLAGS):
        background = check_background(args.background)
        check_device(args.device, "device")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(out, "exists and is not a folder")
    scene = load_scene(args.scene)
    origin, cams = select_views(args, scene)
    with naming(FLAGS):
        renderer = start_renderer(args.backend, args.device)
    from harness.io.files import make_output_folder, refuse_inputs

    make_output_folder(out)  # created, writable (not /proc, not read-only), stale temp files swept
    refuse_inputs(*(out / n for n in ("cameras.json", "coverage.json", "contact_sheet.png")),  # before any write
                  *(out / f"{i:03d}_{_safe(c.name)}.{args.format}" for i, c in enumerate(cams)))
    sheet, labels = ContactSheet(len(cams), background=background), []
    try:
        for i, cam in enumerate(cams):  # one image in memory at a time: rendered, written, thumbnailed
            img = renderer.render(scene, cam, background=background)
            _save_image(img, out / f"{i:03d}_{_safe(cam.name)}.{args.format}", args.format)
            labels.append(cam.name or f"view {i}")
            sheet.add(img, labels[-1])
            del img
        covs = sheet.write(out / "contact_sheet.png")
        write_3dgs_cameras(cams, out / "cameras.json")
        record = [{"view": lab, "width": c.width, "height": c.height, "coverage": round(v, 4)}
                  for lab, c, v in zip(labels, cams, covs)]
        atomic_write_text(out / "coverage.json", json.dumps(record, indent=1))
    except OSError as err:  # full disk, folder removed meanwhile: each file is whole or absent
        raise InputError(err.filename or out, f"cannot write: {err.strerror or err}") from None
    finally:
        renderer.close()
    for r in record:
        print(f"{r['view']:>24}  {r['width']}x{r['height']}  coverage {100 * r['coverage']:5.1f}%")
    print(f"wrote {len(cams)} views ({origin}), contact_sheet.png, cameras.json and coverage.json to {out}")
    return 0
