"""`harness render SCENE (--cameras FILE | --rig NAME) --out DIR`: render views of a scene.

Writes into DIR (created if needed; every file written atomically):

* ``NNN_<view name>.png`` (image clamped to [0, 1], 8-bit, no gamma: the linear render as-is) or
  ``.npy`` (float32 H×W×3, linear, unclamped: exactly what the renderer returned);
* ``contact_sheet.png`` (all rendered views, labelled with their coverage, see
  :mod:`harness.views.contact_sheet`), ``coverage.json`` (per view) and ``cameras.json`` (the views, 3DGS
  format, so a render can be repeated with ``--cameras``).

Views: ``--rig`` builds a synthetic rig (:mod:`harness.views.rigs`; ``default`` = the scene's table entry,
``auto`` for unknown scenes), split into train/test. ``--cameras`` reads a camera file
(:mod:`harness.io.cameras`); its held-out ``test`` split is every 8th view (index i with i % 8 == 0,
the 3DGS ``llffhold`` convention), ``train`` the others. ``--longest-side`` resizes camera-file
views (default: as stored) and sets the rig resolution (default 1024).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from harness.core.errors import InputError
from harness.io.files import atomic_write_npy, atomic_write_text, atomic_write_with

NAME = "render"
HELP = "render a scene from a camera file or a synthetic rig (images + contact sheet)"
RIG_CHOICES = ("default", "orbit", "room", "forward", "auto")
LLFF_HOLD = 8


def add_arguments(parser) -> None:
    parser.add_argument("scene", help="scene file/folder or dataset name (bonsai-7k, playbot, ...)")
    views = parser.add_mutually_exclusive_group(required=True)
    views.add_argument("--cameras", metavar="FILE", help="camera file: cameras.json, transforms.json, "
                       "COLMAP model folder, or a PLY with camera comments")
    views.add_argument("--rig", choices=RIG_CHOICES, help="synthetic rig (default: the scene's table entry)")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder")
    parser.add_argument("--backend", choices=("gl", "reference"), default="gl", help="renderer (default gl)")
    parser.add_argument("--device", default=None, help="torch device for the reference renderer")
    parser.add_argument("--format", choices=("png", "npy"), default="png", help="image format (default png)")
    parser.add_argument("--split", choices=("test", "train", "all"), default="test", help="views to render")
    parser.add_argument("--longest-side", type=int, default=None, metavar="N", help="image size (long side)")
    parser.add_argument("--n-train", type=int, default=48, help="rig training views (default 48)")
    parser.add_argument("--n-test", type=int, default=8, help="rig held-out views (default 8)")
    parser.add_argument("--seed", type=int, default=0, help="rig seed (default 0)")
    parser.add_argument("--aspect", type=float, default=None, help="rig width/height (default: table or 4/3)")
    parser.add_argument("--background", default="0,0,0", metavar="R,G,B", help="background colour in [0, 1]")


def _background(text: str) -> tuple[float, float, float]:
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != 3 or not all(np.isfinite(vals)):
        raise InputError("--background", f"expected three numbers R,G,B, got {text!r}")
    return vals


def select_views(args, scene):
    """The cameras to render, per ``--cameras``/``--rig``, ``--split`` and ``--longest-side``."""
    if args.longest_side is not None and args.longest_side < 1:
        raise InputError("--longest-side", "must be a positive number of pixels")
    if args.cameras:
        from harness.io.cameras import load_cameras

        cams = load_cameras(args.cameras)
        if args.longest_side:
            cams = [c.resized(args.longest_side) for c in cams]
        test = [c for i, c in enumerate(cams) if i % LLFF_HOLD == 0]
        train = [c for i, c in enumerate(cams) if i % LLFF_HOLD != 0]
    else:
        from harness.views.rigs import scene_rig

        if args.n_test < 1 or args.n_train < 0:
            raise InputError("--n-test/--n-train", "need at least one test view and no negative counts")
        if args.aspect is not None and not args.aspect > 0:
            raise InputError("--aspect", "must be a positive width/height ratio")
        try:
            views = scene_rig(args.scene, scene, None if args.rig == "default" else args.rig,
                              n_train=args.n_train, n_test=args.n_test, seed=args.seed,
                              longest_side=args.longest_side or 1024, aspect=args.aspect)
        except ValueError as err:
            raise InputError(args.scene, f"cannot build a rig: {err}") from None
        train, test = views.train, views.test
        cams = views.all
    selected = {"test": test, "train": train, "all": cams}[args.split]
    if not selected:
        raise InputError("--split", f"the {args.split!r} split has no views")
    return selected


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
    from harness.io.cameras import write_3dgs_cameras
    from harness.io.scenes import load_scene
    from harness.views.contact_sheet import write_contact_sheet

    background = _background(args.background)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(out, "exists and is not a folder")
    scene = load_scene(args.scene)
    cams = select_views(args, scene)
    from renderers import get_renderer

    try:
        renderer = get_renderer(args.backend, args.device)
    except Exception as err:  # noqa: BLE001  no EGL/CUDA here (moderngl, torch errors): usage, not a crash
        raise InputError(f"--backend {args.backend}", f"cannot start the renderer: {err}") from None
    out.mkdir(parents=True, exist_ok=True)
    images, labels = [], []
    try:
        for i, cam in enumerate(cams):
            img = renderer.render(scene, cam, background=background)
            _save_image(img, out / f"{i:03d}_{_safe(cam.name)}.{args.format}", args.format)
            images.append(img)
            labels.append(cam.name or f"view {i}")
    finally:
        renderer.close()
    covs = write_contact_sheet(images, labels, out / "contact_sheet.png", background=background)
    write_3dgs_cameras(cams, out / "cameras.json")
    record = [{"view": lab, "width": c.width, "height": c.height, "coverage": round(v, 4)}
              for lab, c, v in zip(labels, cams, covs)]
    atomic_write_text(out / "coverage.json", json.dumps(record, indent=1))
    for r in record:
        print(f"{r['view']:>24}  {r['width']}x{r['height']}  coverage {100 * r['coverage']:5.1f}%")
    print(f"wrote {len(cams)} views, contact_sheet.png, cameras.json and coverage.json to {out}")
    return 0
