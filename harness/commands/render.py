"""`harness render SCENE [--cameras FILE | --rig NAME] --out DIR`: render views of a scene.

Writes into DIR (created if needed; every file written atomically, one view at a time — a render
holds at most two images in memory, not all of them: a view is written on a worker thread while the
next one is drawn, unless it is larger than :data:`OVERLAP_MAX_BYTES`):

* ``NNN_<view name>.png`` (image clamped to [0, 1], 8-bit, no gamma: the linear render as-is) or
  ``.npy`` (float32 H×W×3, linear, unclamped: exactly what the renderer returned);
* ``contact_sheet.png`` (all rendered views, labelled with their coverage, see
  :mod:`harness.views.contact_sheet`), ``coverage.json`` (per view) and ``cameras.json`` (the views,
  3DGS format, so a render can be repeated with ``--cameras``).

**Predictable views** (so that ``render luigi30.ply`` and ``render luigi`` give images ``compare``
can pair: the same view names at the same sizes). The rule:
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

The rule is :func:`harness.api.views.views` (``harness.cameras`` in Python) and the renderer
:func:`harness.api.images.start_renderer` (``harness.render`` renders into arrays); this module adds
the files.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from harness.core import jsonout
from harness.core.errors import InputError
from harness.core.overlap import overlapped
from harness.io.files import atomic_write_npy, atomic_write_text, atomic_write_with
from harness.views.rigs import ASPECT, LONGEST_SIDE, MAX_VIEWS, N_TEST, N_TRAIN, RIG_CHOICES
from renderers import RENDERERS

NAME = "render"
HELP = "render a scene from a camera file or a synthetic rig (images + contact sheet)"
#: how this command names the API's arguments (:func:`harness.core.errors.naming`)
FLAGS = {"background": "--background", "device": "--device", "backend": "--backend", "longest_side": "--longest-side",
         "up": "--up", "n_test": "--n-test", "n_train": "--n-train", "seed": "--seed", "aspect": "--aspect",
         "split": "--split"}


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


#: a view of more bytes than this is written before the next one is drawn (one full image in memory,
#: not two); smaller ones are written on a worker thread while the next is drawn
OVERLAP_MAX_BYTES = 256 * 2**20


def _safe(name: str) -> str:
    stem = re.sub(r"[^A-Za-z0-9._-]+", "_", Path(name).with_suffix("").as_posix()).strip("._")
    return stem[:80] or "view"


def _save_image(image: np.ndarray, path: Path, fmt: str) -> np.ndarray | None:
    """Write the view; returns its 8-bit pixels when it is a PNG (the contact sheet's thumbnail reuses them)."""
    if fmt == "npy":
        atomic_write_npy(path, np.asarray(image, np.float32))
        return None
    from PIL import Image

    from harness.views.contact_sheet import PNG_LEVEL, to_uint8

    pixels = to_uint8(image)
    atomic_write_with(path, lambda t: Image.fromarray(pixels).save(t, format="PNG", compress_level=PNG_LEVEL))
    return pixels


def run(args) -> int:
    from harness.api.images import check_background, start_renderer
    from harness.api.views import views
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
    with naming(FLAGS):
        origin, cams = views(
            scene,
            cameras=args.cameras,
            rig=args.rig,
            split=args.split,
            longest_side=args.longest_side,
            n_train=args.n_train,
            n_test=args.n_test,
            seed=args.seed,
            aspect=args.aspect,
            up=args.up,
            name=args.scene,
        )
        renderer = start_renderer(args.backend, args.device)
    if hasattr(renderer, "preload_triton"):  # the GL renderer: this process never calls torch.compile
        renderer.preload_triton = False
    from harness.io.files import make_output_folder, refuse_inputs

    make_output_folder(out)  # created, writable (not /proc, not read-only), stale temp files swept
    refuse_inputs(*(out / n for n in ("cameras.json", "coverage.json", "contact_sheet.png")),  # before any write
                  *(out / f"{i:03d}_{_safe(c.name)}.{args.format}" for i, c in enumerate(cams)))
    sheet, labels = ContactSheet(len(cams), background=background), [c.name or f"view {i}" for i, c in enumerate(cams)]

    def draw(i: int) -> tuple[int, np.ndarray]:
        return i, renderer.render(scene, cams[i], background=background)

    def keep(drawn: tuple[int, np.ndarray]) -> None:
        """Write and thumbnail view ``i``."""
        i, img = drawn
        pixels = _save_image(img, out / f"{i:03d}_{_safe(cams[i].name)}.{args.format}", args.format)
        sheet.add(img, labels[i], pixels=pixels)

    try:  # the previous view written while this one is drawn (GL waits without the GIL), large ones before
        for _ in overlapped(range(len(cams)), draw, keep, inline=lambda d: d[1].nbytes > OVERLAP_MAX_BYTES,
                            name="render-writer"):
            pass
        covs = sheet.write(out / "contact_sheet.png")
        write_3dgs_cameras(cams, out / "cameras.json")
        record = [{"view": lab, "width": c.width, "height": c.height, "coverage": round(v, 4)}
                  for lab, c, v in zip(labels, cams, covs)]
        atomic_write_text(out / "coverage.json", jsonout.dumps(record, indent=1))
    except OSError as err:  # full disk, folder removed meanwhile: each file is whole or absent
        raise InputError(err.filename or out, f"cannot write: {err.strerror or err}") from None
    finally:
        renderer.close()
    name_width = max((len(r["view"]) for r in record), default=0)  # names left-aligned: no blank first column
    for r in record:
        print(f"{r['view']:<{name_width}}  {r['width']}x{r['height']}  coverage {100 * r['coverage']:5.1f}%")
    print(f"wrote {len(cams)} views ({origin}), contact_sheet.png, cameras.json and coverage.json to {out}")
    return 0
