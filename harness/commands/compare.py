"""`harness compare A B [--json]`: PSNR, SSIM and LPIPS-VGG of two image files (PNG or .npy).

``--metrics mpeg`` scores as MPEG's mpeg-gsc-metrics does (:mod:`harness.metrics.mpeg`): the images
are quantised to 8 bit like the tool's renders (8-bit PNGs are taken as they are) and the keys
``rgb_psnr, yuv_psnr, yuv_ssim, rgb_psnr_om, yuv_psnr_om, yuv_ssim_om`` are printed (PSNRs capped at
999.99, never infinite); ``--qmiv`` computes the same keys in the tool's QMIV mode. ``--mask FILE``
(PNG/.npy, non-zero = occupied) restricts the OM metrics and adds ``occupancy`` (%); without it the
mask is all ones, as in the tool's maskless overload (OM = full frame). ``--metrics`` takes metric
and family names, comma-separated (``mpeg,lpips``; default ``3dgs``).

JSON has no infinity, so with ``--json`` an infinite PSNR (identical images) is written as
``"psnr": null`` together with ``"psnr_inf": true``; ``psnr_inf`` is always present (false otherwise).
The same applies to the ``psnr_y/u/v/yuv`` keys of ``--yuv``: ``null`` with ``"<key>_inf": true``.
Mismatched sizes, NaN pixels and unreadable files are input errors (one line, exit status 2).
The measuring is :func:`harness.api.compare` (``harness.compare`` in Python); this module prints it.
"""

from __future__ import annotations

import json
import math

NAME = "compare"
HELP = "compare two images (PNG or .npy): PSNR, SSIM, LPIPS-VGG"


def add_arguments(parser) -> None:
    parser.add_argument("a", metavar="A", help="first image (PNG or .npy; the reference)")
    parser.add_argument("b", metavar="B", help="second image (same size)")
    parser.add_argument(
        "--json",
        action="store_true",
        help="print one JSON object: psnr, ssim, lpips (an infinite PSNR is null with psnr_inf true)",
    )
    parser.add_argument(
        "--yuv",
        action="store_true",
        help="also report float BT.709 Y/U/V PSNR and (6Y+U+V)/8 (video CTC style; "
        "the splat tool's YUV-PSNR is --metrics mpeg)",
    )
    parser.add_argument("--device", default=None, help="torch device for LPIPS/SSIM (default: cuda if present)")
    parser.add_argument("--metrics", default="3dgs", metavar="NAMES",
                        help="comma-separated metric or family names: 3dgs (psnr, ssim, lpips), mpeg (the "
                             "mpeg-gsc-metrics set), or single metrics (default 3dgs)")
    parser.add_argument("--qmiv", action="store_true", help="MPEG metrics in the tool's QMIV mode "
                        "(integer BT.709, 4:1:1 weights; same keys)")
    parser.add_argument("--mask", metavar="FILE", help="occupancy mask for the MPEG OM metrics (PNG or .npy, "
                        "non-zero = occupied); also prints occupancy (%%)")


def _json_ready(metrics: dict) -> dict:
    out = {}
    for key, value in metrics.items():
        if key.startswith("psnr") and not isinstance(value, str):
            inf = math.isinf(value)
            out[key] = None if inf else value
            out[f"{key}_inf"] = inf
        else:
            out[key] = value
    return out


#: how this command names the API's arguments (:func:`harness.core.errors.naming`)
FLAGS = {"metrics": "--metrics", "device": "--device", "mask": "--mask"}


def run(args) -> int:
    from harness.api.images import compare
    from harness.core.errors import naming

    with naming(FLAGS):
        metrics = compare(args.a, args.b, args.metrics, device=args.device, yuv=args.yuv, qmiv=args.qmiv,
                          mask=args.mask)
    if args.json:
        print(json.dumps(_json_ready(metrics), allow_nan=False))
    else:
        for key, value in metrics.items():
            if isinstance(value, str):
                print(f"{key:11s} {value}")
            else:
                print(f"{key:11s} {value:.6f}" if not math.isinf(value) else f"{key:11s} inf")
    return 0
