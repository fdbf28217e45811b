"""`harness render SCENE [--cameras FILE | --rig NAME] --out DIR`: render views of a scene.

Writes into DIR (created if needed; every file written atomically):

* ``NNN_<view name>.png`` (image clamped to [0, 1], 8-bit, no gamma: the linear render as-is) or
  ``.npy`` (float32 H×W×3, linear, unclamped: exactly what the renderer returned);
* ``contact_sheet.png`` (all rendered views, labelled with their coverage, see
  :mod:`harness.views.contact_sheet`), ``coverage.json`` (per view) and ``cameras.json`` (the views,
  3DGS format, so a render can be repeated with ``--cameras``).

Views come from the scene's content and the flags, never from its file name:

* ``--cameras FILE`` reads a camera file (:mod:`harness.io.cameras`);
* ``--rig NAME`` (orbit, room, forward, auto) builds that synthetic rig from the flags alone
  (``--up``, ``--aspect``, ``--n-train/--n-test``, ``--seed``, ``--longest-side``): the same flags give
  the same rig for any scene. A rig is fitted to the content it is given, so a pruned scene's rig
  can sit slightly differently; for identical views render the second scene with
  ``--cameras DIR/cameras.json`` of the first render;
* neither: the cameras embedded in the scene's header when it has any; else, for a named dataset
  (given by name, or a file with a dataset's exact content), that dataset's own rig
  (:data:`harness.views.rigs.SCENE_RIGS`); else ``auto``.

Camera files and embedded cameras: the held-out ``test`` split is every 8th view (index i with
i % 8 == 0, the 3DGS ``llffhold`` convention), ``train`` the others; ``--longest-side`` resizes them
(default: as stored). Rigs: ``--longest-side`` is the resolution (default 1024).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from harness.core.errors import InputError
from harness.io.files import atomic_write_npy, atomic_write_text, atomic_write_with
from harness.views.rigs import LONGEST_SIDE, N_TEST, N_TRAIN, RIG_CHOICES
from renderers import RENDERERS

NAME = "render"
HELP = "render a scene from a camera file or a synthetic rig (images + contact sheet)"
LLFF_HOLD = 8


def add_arguments(parser) -> None:
    parser.add_argument("scene", help="scene file/folder or dataset name (bonsai-7k, playbot, ...)")
    views = parser.add_mutually_exclusive_group()
    views.add_argument("--cameras", metavar="FILE", help="camera file: cameras.json, transforms.json, "
                       "COLMAP model folder, or a PLY with camera comments")
    views.add_argument("--rig", choices=RIG_CHOICES, help="synthetic rig from the flags alone; `default`: the "
                       "scene's own (its embedded cameras, a dataset's rig, else auto), as without the flag")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder")
    parser.add_argument("--backend", choices=tuple(RENDERERS.names()), default="gl", help="renderer (default gl)")
    parser.add_argument("--device", default=None, help="torch device for the reference renderer")
    parser.add_argument("--format", choices=("png", "npy"), default="png", help="image format (default png)")
    parser.add_argument("--split", choices=("test", "train", "all"), default="test", help="views to render")
    parser.add_argument("--longest-side", type=int, default=None, metavar="N",
                        help=f"image size (long side; rigs default {LONGEST_SIDE})")
    parser.add_argument("--n-train", type=int, default=N_TRAIN, help=f"rig training views (default {N_TRAIN})")
    parser.add_argument("--n-test", type=int, default=N_TEST, help=f"rig held-out views (default {N_TEST})")
    parser.add_argument("--seed", type=int, default=0, help="rig seed (default 0)")
    parser.add_argument("--aspect", type=float, default=None, help="rig width/height (default: the rig's own, 4/3)")
    parser.add_argument("--up", default=None, metavar="X,Y,Z", help="world direction drawn upwards (default 0,-1,0)")
    parser.add_argument("--background", default="0,0,0", metavar="R,G,B", help="background colour in [0, 1]")


def _background(text: str) -> tuple[float, float, float]:
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != 3 or not all(np.isfinite(vals)) or not all(0.0 <= v <= 1.0 for v in vals):
        raise InputError("--background", f"expected three numbers R,G,B in [0, 1], got {text!r}")
    return vals


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
        train, test = _split_llff(cams)
    else:
        from harness.io.datasets import identify
        from harness.views.rigs import scene_rig

        if args.n_test < 1 or args.n_train < 0 or args.n_test > 10000 or args.n_train > 10000:
            raise InputError("--n-test/--n-train", "need 1..10000 test views and 0..10000 training views")
        if args.aspect is not None and not (np.isfinite(args.aspect) and args.aspect > 0):
            raise InputError("--aspect", "must be a positive width/height ratio")
        rig = args.rig or "default"
        dataset = identify(args.scene) if rig == "default" else None
        try:
            views = scene_rig(dataset, scene, rig, n_train=args.n_train, n_test=args.n_test, seed=args.seed,
                              longest_side=args.longest_side or LONGEST_SIDE, aspect=args.aspect, up=up)
        except ValueError as err:
            raise InputError(args.scene, f"cannot build a rig: {err}") from None
        origin = f"rig {views.rig}" + (f" (the {dataset} dataset's own)" if dataset else "")
        train, test, cams = views.train, views.test, views.all
    selected = {"test": test, "train": train, "all": cams}[args.split]
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
    from harness.core.devices import check_device
    from harness.io.cameras import write_3dgs_cameras
    from harness.io.scenes import load_scene
    from harness.views.contact_sheet import write_contact_sheet

    background = _background(args.background)
    check_device(args.device, "--device")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(out, "exists and is not a folder")
    scene = load_scene(args.scene)
    origin, cams = select_views(args, scene)
    from renderers import get_renderer

    try:
        renderer = get_renderer(args.backend, args.device)
    except Exception as err:  # noqa: BLE001  no EGL/CUDA here (moderngl, torch errors): usage, not a crash
        raise InputError(f"--backend {args.backend}", f"cannot start the renderer: {err}") from None
    from harness.io.files import make_output_folder, refuse_inputs

    make_output_folder(out)  # created, writable (not /proc, not read-only), stale temp files swept
    refuse_inputs(*(out / n for n in ("cameras.json", "coverage.json", "contact_sheet.png")),  # before any write
                  *(out / f"{i:03d}_{_safe(c.name)}.{args.format}" for i, c in enumerate(cams)))
    images, labels = [], []
    try:
        for i, cam in enumerate(cams):
            img = renderer.render(scene, cam, background=background)
            _save_image(img, out / f"{i:03d}_{_safe(cam.name)}.{args.format}", args.format)
            images.append(img)
            labels.append(cam.name or f"view {i}")
        covs = write_contact_sheet(images, labels, out / "contact_sheet.png", background=background)
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
