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
    parser.add_argument("--yuv", action="store_true", help="also report float BT.709 Y/U/V PSNR and (6Y+U+V)/8 (video CTC style; "
                        "the splat tool's YUV-PSNR is --metrics mpeg)")
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


def metric_names(text: str, qmiv: bool = False) -> tuple[str, ...]:
    """Metric names from a comma-separated list of metric and family names (InputError if unknown);
    with ``qmiv`` the mpeg family and MPEG names become their QMIV-mode counterparts."""
    from harness.core.errors import InputError
    from harness.metrics.registry import METRICS, expand, requestable

    words = [w.strip() for w in text.split(",") if w.strip()]
    known = requestable()
    bad = [w for w in words if w not in known]
    if bad or not words:
        raise InputError("--metrics", f"unknown metric or family {', '.join(bad) or repr(text)}; known: {', '.join(known)}")
    names = expand(words)
    if qmiv:
        qm = {m.name for m in METRICS if m.family == "mpeg-qmiv"}
        names = tuple(dict.fromkeys(n + "_qmiv" if n + "_qmiv" in qm else n for n in names))
    return names


def run(args) -> int:
    import numpy as np
    import torch

    from harness.metrics.images import check_same_size, read_image
    from harness.metrics.lpips_vgg import LpipsVGG
    from harness.metrics.suite import compare_images

    names = metric_names(args.metrics, args.qmiv)
    a, b = read_image(args.a), read_image(args.b)
    check_same_size(a, b, args.a, args.b)
    mask = None
    if args.mask:
        m = read_image(args.mask)
        check_same_size(a, m, args.a, args.mask)
        mask = np.any(m != 0, axis=2)
    from harness.core.devices import check_device

    device = None if check_device(args.device, "--device") is None else torch.device(args.device)
    model = LpipsVGG(device=device) if "lpips" in names else None
    metrics = compare_images(a, b, lpips_model=model, yuv=args.yuv, names=names, mask=mask)
    if args.qmiv:  # same keys in both modes; the mode is said once
        metrics = {k[:-5] if k.endswith("_qmiv") else k: v for k, v in metrics.items()}
        metrics["mode"] = "qmiv"
    if mask is None:
        metrics.pop("occupancy", None)
    if args.json:
        print(json.dumps(_json_ready(metrics), allow_nan=False))
    else:
        for key, value in metrics.items():
            if isinstance(value, str):
                print(f"{key:11s} {value}")
            else:
                print(f"{key:11s} {value:.6f}" if not math.isinf(value) else f"{key:11s} inf")
    return 0
