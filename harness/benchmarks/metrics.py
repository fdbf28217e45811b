"""`harness bench metrics`: LPIPS-VGG per pruned image, naive pair vs cached reference, same run.

*Naive* is what a script using the ``lpips`` package does: ``lpips.LPIPS(net='vgg')(ref, img)``
under ``torch.no_grad`` (both trunk passes every time, default layout). *Cached* is
:class:`~harness.metrics.lpips_vgg.LpipsVGG`: the reference's features computed once per view, then
one trunk pass per pruned image. Pairs are timed interleaved (naive, cached, naive, ...) so machine
noise hits both alike; the goal is ``cached / naive <= 0.5``. PSNR and SSIM times per image, the
feature memory per view, the agreement of the two LPIPS paths and (``--bf16``) the speed and error
of the bfloat16 trunk are reported too. Images: scikit-image's astronaut resized to the size asked,
degraded by Gaussian blur and noise to stand in for pruned renders.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

NAME = "metrics"
HELP = "LPIPS-VGG naive pair vs cached-reference time per pruned image (+ PSNR/SSIM times)"
TARGET_RATIO = 0.5


def add_arguments(parser) -> None:
    parser.add_argument("--width", type=int, default=1024)
    parser.add_argument("--height", type=int, default=768)
    parser.add_argument("--pruned", type=int, default=4, help="pruned images per view (default 4)")
    parser.add_argument("--device", default=None, help="torch device (default: cuda if present)")
    parser.add_argument("--bf16", action="store_true", help="also time the bfloat16 trunk and report its error")


def _images(width: int, height: int, n: int) -> tuple[np.ndarray, list[np.ndarray]]:
    from harness.benchmarks._common import require

    require("skimage", "the metrics benchmark's test images")
    from skimage import data, filters, transform

    ref = transform.resize(data.astronaut().astype(np.float32) / 255.0, (height, width, 3),
                           order=1, anti_aliasing=True).astype(np.float32)
    rng = np.random.default_rng(0)
    pruned = []
    for i in range(n):
        img = filters.gaussian(ref, sigma=0.5 + 0.5 * i, channel_axis=-1)
        img = img + rng.normal(0.0, 0.01 * (i + 1), img.shape)
        pruned.append(np.clip(img, 0, 1).astype(np.float32))
    return ref, pruned


def _timed(fn):
    t0 = time.perf_counter()
    value = fn()
    return time.perf_counter() - t0, value


def run(args) -> int:
    import torch

    from harness.benchmarks._common import out_dir, peak_rss_mb, write_result
    from harness.metrics.lpips_vgg import LpipsVGG
    from harness.metrics.lpips_weights import load_backbone, new_lpips_module
    from harness.metrics.psnr import psnr
    from harness.metrics.ssim import ssim

    folder = out_dir(args)  # created and probed before any work
    ref, pruned = _images(args.width, args.height, args.pruned)
    cached = LpipsVGG(device=args.device)
    device = cached.device
    naive = new_lpips_module(pretrained_lin=True)
    naive.net.load_state_dict(load_backbone()["net"])
    naive.to(device)

    def to_t(img):
        return torch.from_numpy(img).permute(2, 0, 1)[None].to(device)

    def naive_pair(img):
        with torch.no_grad():
            return float(naive(to_t(ref), to_t(img), normalize=True).item())

    def sync(fn):
        def wrapped():
            out = fn()
            if device.type == "cuda":
                torch.cuda.synchronize()
            return out
        return wrapped

    # warm-up at full size, not timed (oneDNN primitive creation, CUDA context)
    naive_pair(pruned[0])
    cached.features(ref)
    t_features, feats = _timed(sync(lambda: cached.features(ref)))
    naive_s, cached_s, diffs, values = [], [], [], []
    for img in pruned:
        tn, vn = _timed(sync(lambda img=img: naive_pair(img)))
        tc, vc = _timed(sync(lambda img=img: cached.distance(feats, img)))
        naive_s.append(tn)
        cached_s.append(tc)
        values.append(vc)
        diffs.append(abs(vn - vc))
    psnr_s = [_timed(lambda img=img: psnr(ref, img))[0] for img in pruned]
    ssim_s = [_timed(lambda img=img: ssim(ref, img, device=device))[0] for img in pruned]
    naive_med, cached_med = statistics.median(naive_s), statistics.median(cached_s)
    ratio = cached_med / naive_med
    result = {
        "image": [args.width, args.height], "pruned_images": args.pruned, "device": str(device),
        "threads": torch.get_num_threads(),
        "lpips_naive_pair_s": naive_med, "lpips_naive_pair_samples_s": naive_s,
        "lpips_reference_features_s": t_features,
        "lpips_cached_per_pruned_s": cached_med, "lpips_cached_samples_s": cached_s,
        "ratio_cached_over_naive": ratio, "target_ratio": TARGET_RATIO, "meets_target": ratio <= TARGET_RATIO,
        "lpips_values": values, "lpips_max_abs_diff_naive_vs_cached": max(diffs),
        "reference_features_mb": feats.nbytes / 2**20,
        "psnr_per_image_s": statistics.median(psnr_s), "ssim_per_image_s": statistics.median(ssim_s),
    }
    if args.bf16:
        fast = LpipsVGG(device=device, precision="bfloat16")
        bf_feats = fast.features(ref)
        bf_s, bf_err = [], []
        for img, v in zip(pruned, values):
            t, vb = _timed(sync(lambda img=img: fast.distance(bf_feats, img)))
            bf_s.append(t)
            bf_err.append(abs(vb - v))
        result.update({"lpips_bf16_per_pruned_s": statistics.median(bf_s),
                       "lpips_bf16_max_abs_err": max(bf_err),
                       "lpips_bf16_max_rel_err": max(e / v for e, v in zip(bf_err, values))})
    result["peak_rss_mb"] = peak_rss_mb()
    write_result(NAME, result, _markdown(result), out=folder)
    print(_markdown(result))
    return 0


def _markdown(r: dict) -> str:
    w, h = r["image"]
    lines = [
        f"# LPIPS-VGG: naive pair vs cached reference ({w}x{h}, {r['device']}, {r['threads']} threads)",
        "",
        "| quantity | value |",
        "|---|---|",
        f"| naive pair (lpips package, 2 trunk passes), median | {r['lpips_naive_pair_s']:.3f} s |",
        f"| reference features, once per view | {r['lpips_reference_features_s']:.3f} s |",
        f"| cached: per additional pruned image, median | {r['lpips_cached_per_pruned_s']:.3f} s |",
        (f"| **ratio cached / naive** (target <= {r['target_ratio']}) | **{r['ratio_cached_over_naive']:.3f}** "
         f"({'met' if r['meets_target'] else 'NOT met'}) |"),
        f"| max abs LPIPS difference naive vs cached | {r['lpips_max_abs_diff_naive_vs_cached']:.2e} |",
        f"| reference features memory per view | {r['reference_features_mb']:.0f} MiB |",
        f"| PSNR per image | {r['psnr_per_image_s'] * 1e3:.1f} ms |",
        f"| SSIM per image | {r['ssim_per_image_s'] * 1e3:.1f} ms |",
    ]
    if "lpips_bf16_per_pruned_s" in r:
        lines += [
            f"| bfloat16 trunk: per pruned image (not the default) | {r['lpips_bf16_per_pruned_s']:.3f} s |",
            (f"| bfloat16 max abs / rel LPIPS error vs float32 | {r['lpips_bf16_max_abs_err']:.2e} / "
             f"{r['lpips_bf16_max_rel_err']:.2%} |"),
        ]
    naive = ", ".join(f"{s:.2f}" for s in r["lpips_naive_pair_samples_s"])
    cached = ", ".join(f"{s:.2f}" for s in r["lpips_cached_samples_s"])
    lines += ["", f"Samples (s): naive [{naive}], cached [{cached}]; peak RSS {r['peak_rss_mb']:.0f} MiB."]
    return "\n".join(lines)
