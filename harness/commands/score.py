"""`harness score SOURCE PROCESSED`: score a processed scene against its source as mpeg-gsc-metrics does.

The MPEG tool (``mpeg-gsc-metrics -a SOURCE -b PROCESSED --useCameraPosition=1 --width W --height H``)
renders both PLYs from the same viewpoints, on black, quantises each render to 8 bit and computes
RGB-PSNR, YUV-PSNR, YUV-SSIM and their occupancy-masked variants per view (mask: the union of both
renders' occupancy), then averages every value over the views. This command does the same with
this harness's renderer (``--renderer``, default ``gl``) and the tool's arithmetic
(:mod:`harness.metrics.mpeg`, bit for bit; ``--qmiv`` for its QMIV mode).

Viewpoints, in this order:

* ``--cameras FILE``: any camera file :func:`harness.io.cameras.load_cameras` reads (COLMAP,
  cameras.json, transforms.json, a PLY with camera lines);
* ``-n/--views N``: the N viewpoints the tool places itself (``mpeg-gsc-metrics -n N`` without
  ``--useCameraPosition``): a Fibonacci sphere of radius 5 around the source's bounding-box centre,
  focal 2000 px, 1024×768 (:mod:`harness.views.mpeg_viewpoints`);
* else the ``camera_position`` lines of SOURCE's header (gsTools syntax; the CTC's
  ``--useCameraPosition=1``), else PROCESSED's; when both carry lines they must be the same cameras
  (as the tool requires);
* else, like the tool, its default ``-n 16``.

Every camera is rendered as the tool renders it: a ``--width × --height`` window (default: the
cameras' own size; for header lines without a size and for placed viewpoints, the tool's 1024×768),
principal point at the centre and focal.y on both axes (the tool's projection). The focal length is
*not* rescaled with the window (as in the tool), so a smaller window is the centre **crop** of the
view, not a scaled-down image; the output says so. Prints one row per view and the mean
(``--json``: one object; ``--csv``: CSV with a final ``mean`` row).
"""

from __future__ import annotations

import csv
import io
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.core.errors import InputError
from harness.views.mpeg_viewpoints import DEFAULT_VIEWS

NAME = "score"
HELP = "score a processed scene against its source like mpeg-gsc-metrics (same cameras, 8-bit renders)"
COLUMNS = (("rgb_psnr", "RGB-PSNR", 4), ("yuv_psnr", "YUV-PSNR", 4), ("yuv_ssim", "YUV-SSIM", 6),
           ("rgb_psnr_om", "OM-RGB-PSNR", 4), ("yuv_psnr_om", "OM-YUV-PSNR", 4), ("yuv_ssim_om", "OM-YUV-SSIM", 6),
           ("rgb_ivssim", "RGB-IVSSIM", 6), ("yuv_ivssim", "YUV-IVSSIM", 6), ("occupancy", "Occupancy%", 2))


def add_arguments(parser) -> None:
    from renderers import RENDERERS

    parser.add_argument("source", help="the original scene (.ply, or any scene the harness reads)")
    parser.add_argument("processed", help="the processed (pruned, decoded ...) scene")
    views = parser.add_mutually_exclusive_group()
    views.add_argument("--cameras", metavar="FILE", help="viewpoints from a camera file (default: the camera_position "
                       "lines of the source's PLY header, else the processed one's, else -n 16)")
    views.add_argument("-n", "--views", type=int, metavar="N", help="place N viewpoints as mpeg-gsc-metrics -n N does "
                       f"(radius-5 sphere around the source's box centre, focal 2000 px; the tool's default is "
                       f"{DEFAULT_VIEWS}, used when no file has cameras)")
    parser.add_argument(
        "--width",
        type=int,
        help="render width in pixels (the tool's --width). The focal length is "
        "kept, so a smaller window is the centre crop of the view (as the tool does), not a scaled image",
    )
    parser.add_argument("--height", type=int, help="render height in pixels (the tool's --height; crops like --width)")
    parser.add_argument("--renderer", default="gl", choices=RENDERERS.names(), help="renderer (default gl)")
    parser.add_argument("--device", default=None, help="torch device of the renderer/LPIPS (default: automatic)")
    parser.add_argument("--qmiv", action="store_true", help="the tool's QMIV mode (integer BT.709, 4:1:1)")
    parser.add_argument("--lpips", action="store_true", help="also LPIPS-VGG per view (on the float renders)")
    out = parser.add_mutually_exclusive_group()
    out.add_argument("--json", action="store_true", help="print one JSON object (views and mean)")
    out.add_argument("--csv", action="store_true", help="print CSV: one row per view, then the mean")


def tool_camera(cam, width: int | None, height: int | None):
    """The camera as the metric tool renders it: ``width × height`` (default: its own), principal
    point at the centre, focal.y on both axes, the pose unchanged."""
    from harness.core.cameras import Camera

    w, h = int(width or cam.width), int(height or cam.height)
    return Camera(cam.world_to_cam, cam.fy, cam.fy, w / 2.0, h / 2.0, w, h, cam.name)


def _same(a, b) -> bool:
    return len(a) == len(b) and all(np.allclose(x.world_to_cam, y.world_to_cam, atol=1e-6)
                                    and abs(x.fy - y.fy) <= 1e-6 * max(1.0, x.fy) for x, y in zip(a, b))


@dataclass(frozen=True)
class Viewpoints:
    cameras: list          # as the tool renders them
    origin: str            # where they came from, for people
    native: tuple | None   # the cameras' own sizes when the window crops them, else None


def _placed(args, source, n: int, why: str) -> Viewpoints:
    from harness.views.mpeg_viewpoints import ViewpointError, tool_viewpoints

    if not 1 <= n <= 10_000:
        raise InputError("--views", f"must be between 1 and 10000, got {n}")
    try:
        cams, c = tool_viewpoints(source.means, n, args.width, args.height)
    except ViewpointError as err:
        raise InputError(args.source, f"{err}; give --cameras") from None
    return Viewpoints(cams, f"mpeg-gsc-metrics' own viewpoints (-n {n}{why}): radius-5 sphere around the source's "
                            f"box centre ({c[0]:.4g}, {c[1]:.4g}, {c[2]:.4g}), focal 2000 px", None)


def select_cameras(args, source, processed) -> Viewpoints:
    """The viewpoints, in the order of the module docstring."""
    from harness.io.cameras import embedded_cameras, load_cameras
    from harness.views.mpeg_viewpoints import DEFAULT_VIEWS

    for flag in ("width", "height"):
        v = getattr(args, flag)
        if v is not None and not 1 <= v <= 16384:
            raise InputError(f"--{flag}", f"must be between 1 and 16384 pixels, got {v}")
    if (args.width is None) != (args.height is None):
        raise InputError("--width/--height", "give both or neither")
    if args.views is not None:
        return _placed(args, source, args.views, "")
    if args.cameras:
        cams, origin = load_cameras(args.cameras), args.cameras
    else:
        a = embedded_cameras(source)
        b = embedded_cameras(processed)
        if a and b and not _same(a, b):
            raise InputError(args.processed, f"its {len(b)} header cameras differ from the source's {len(a)}; "
                                             "the tool needs the same viewpoints (or give --cameras or -n)")
        cams = a or b
        if not cams:
            return _placed(args, source, DEFAULT_VIEWS, ", its default: no PLY header has camera_position lines")
        origin = f"{'source' if a else 'processed'} PLY header"
    sizes = tuple(sorted({(c.width, c.height) for c in cams}))
    crops = args.width is not None and sizes != ((args.width, args.height),)
    return Viewpoints([tool_camera(c, args.width, args.height) for c in cams], origin, sizes if crops else None)


def window_note(vp: Viewpoints) -> str | None:
    """What a window other than the cameras' own size means (the tool crops; it does not scale)."""
    if vp.native is None:
        return None
    w, h = vp.cameras[0].width, vp.cameras[0].height
    own = " or ".join(f"{a}x{b}" for a, b in vp.native)
    return (f"window {w}x{h}: the centre crop of each {own} view (focal length kept, as mpeg-gsc-metrics "
            "renders it; the image is not scaled)")


def score_views(source, processed, cams, renderer, *, qmiv: bool = False, lpips=None, progress=None) -> list[dict]:
    """Per-view tool metrics (and LPIPS) of ``processed`` against ``source``, rendered on black.

    A view's metrics run in a second thread while the next view renders: the renderer holds the
    interpreter lock only in its own calls and the metrics' kernels release it, so the two overlap.
    Rows come back (and ``progress`` sees them) in view order, each value the one computed alone."""
    from harness.core.overlap import overlapped
    from harness.metrics.mpeg import occupancy_mask, tool_metrics

    def draw(i: int) -> tuple:
        t0 = time.perf_counter()
        a, alpha_a = renderer.render_with_alpha(source, cams[i], (0.0, 0.0, 0.0))
        b, alpha_b = renderer.render_with_alpha(processed, cams[i], (0.0, 0.0, 0.0))
        return cams[i].name or f"view_{i:04d}", a, b, occupancy_mask(alpha_a, alpha_b), time.perf_counter() - t0

    def measure(drawn: tuple) -> dict:
        name, a, b, mask, render_s = drawn
        t0 = time.perf_counter()
        r = tool_metrics(a, b, mask, qmiv=qmiv)
        row = {"view": name, **{k: r[k] for k, _, _ in COLUMNS}}
        if lpips is not None:
            row["lpips"] = float(lpips(a, b))
        row.update(render_s=render_s, metrics_s=time.perf_counter() - t0)
        return row

    rows = []
    for row in overlapped(range(len(cams)), draw, measure, name="score-metrics"):
        rows.append(row)
        if progress:
            progress(row)
    return rows


def _mean(rows: list[dict]) -> dict:
    from harness.metrics.mpeg import average_views

    keys = [k for k in rows[0] if k != "view"]
    return {"view": "mean", **average_views([{k: r[k] for k in keys} for r in rows])}


def _describe(path: str, scene) -> dict:
    p = Path(scene.meta.source or path)
    size = sum(f.stat().st_size for f in p.rglob("*") if f.is_file()) if p.is_dir() else p.stat().st_size
    return {"path": str(p), "splats": len(scene), "bytes": int(size)}


def run(args) -> int:
    from harness.core.extent import check_extent
    from harness.io.scenes import load_scene
    from renderers import get_renderer

    source, processed = load_scene(args.source), load_scene(args.processed)
    for given, scene in ((args.source, source), (args.processed, processed)):
        check_extent(scene, given)
    vp = select_cameras(args, source, processed)
    cams, note = vp.cameras, window_note(vp)
    try:
        renderer = get_renderer(args.renderer, args.device)
    except Exception as err:  # noqa: BLE001  no EGL/CUDA here: usage, not a crash
        raise InputError(f"--renderer {args.renderer}", f"cannot start the renderer: {err}") from None
    if hasattr(renderer, "preload_triton"):  # the GL renderer: this process never calls torch.compile
        renderer.preload_triton = False
    lpips = None
    if args.lpips:
        from harness.metrics.lpips_vgg import LpipsVGG

        lpips = LpipsVGG(device=args.device)
    text = not (args.json or args.csv)
    head = f"{'view':>16} " + " ".join(f"{label:>12}" for _, label, _ in COLUMNS) + ("        LPIPS" if lpips else "")

    def line(row):
        cells = " ".join(f"{row[k]:12.{d}f}" for k, _, d in COLUMNS)
        print(f"{str(row['view'])[:16]:>16} {cells}" + (f" {row['lpips']:12.6f}" if lpips else ""), flush=True)

    src, dst = _describe(args.source, source), _describe(args.processed, processed)
    if text:
        print(f"source    {src['path']}: {src['splats']:,} splats, {src['bytes']:,} bytes")
        print(f"processed {dst['path']}: {dst['splats']:,} splats, {dst['bytes']:,} bytes")
        print(f"{len(cams)} cameras from {vp.origin}, {cams[0].width}x{cams[0].height}, renderer {args.renderer}, "
              f"{'QMIV' if args.qmiv else 'MPEG default'} mode")
        if note:
            print(note)
        print(head)
    try:
        rows = score_views(source, processed, cams, renderer, qmiv=args.qmiv, lpips=lpips,
                           progress=line if text else None)
    finally:
        if hasattr(renderer, "close"):
            renderer.close()
    mean = _mean(rows)
    if args.json:
        from harness.core.jsonout import dumps

        print(dumps({"source": src, "processed": dst, "cameras": vp.origin, "width": cams[0].width,
                     "height": cams[0].height, "window": note or "the cameras' own size",
                     "mode": "qmiv" if args.qmiv else "mpeg", "renderer": args.renderer, "views": rows, "mean": mean}))
    elif args.csv:
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows + [mean])
        sys.stdout.write(buf.getvalue())
    else:
        line(mean)
    return 0
