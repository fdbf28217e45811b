"""`harness compare A B [--json]`: PSNR, SSIM and LPIPS-VGG of two image files (PNG or .npy).

JSON has no infinity, so with ``--json`` an infinite PSNR (identical images) is written as
``"psnr": null`` together with ``"psnr_inf": true``; ``psnr_inf`` is always present (false otherwise).
The same applies to the ``psnr_y/u/v/yuv`` keys of ``--yuv``: ``null`` with ``"<key>_inf": true``.
Mismatched sizes, NaN pixels and unreadable files are input errors (one line, exit status 2).
"""

from __future__ import annotations

import json
import math

NAME = "compare"
HELP = "compare two images (PNG or .npy): PSNR, SSIM, LPIPS-VGG"


def add_arguments(parser) -> None:
    parser.add_argument("a", metavar="A", help="first image (PNG or .npy; the reference)")
    parser.add_argument("b", metavar="B", help="second image (same size)")
    parser.add_argument("--json", action="store_true", help="print one JSON object: psnr, ssim, lpips (an infinite PSNR is null with psnr_inf true)")
    parser.add_argument("--yuv", action="store_true", help="also report BT.709 Y/U/V PSNR and (6Y+U+V)/8")
    parser.add_argument("--device", default=None, help="torch device for LPIPS/SSIM (default: cuda if present)")


def _json_ready(metrics: dict) -> dict:
    out = {}
    for key, value in metrics.items():
        if key.startswith("psnr"):
            inf = math.isinf(value)
            out[key] = None if inf else value
            out[f"{key}_inf"] = inf
        else:
            out[key] = value
    return out


def run(args) -> int:
    import torch

    from harness.metrics.images import check_same_size, read_image
    from harness.metrics.lpips_vgg import LpipsVGG
    from harness.metrics.suite import compare_images

    a, b = read_image(args.a), read_image(args.b)
    check_same_size(a, b, args.a, args.b)
    from harness.core.devices import check_device

    device = None if check_device(args.device, "--device") is None else torch.device(args.device)
    model = LpipsVGG(device=device)
    metrics = compare_images(a, b, lpips_model=model, yuv=args.yuv)
    if args.json:
        print(json.dumps(_json_ready(metrics), allow_nan=False))
    else:
        for key, value in metrics.items():
            print(f"{key:9s} {value:.6f}" if not math.isinf(value) else f"{key:9s} inf")
    return 0
