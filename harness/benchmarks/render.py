"""`harness bench render`: seconds per view and peak memory of the GL and reference renderers.

For one scene (default ``bonsai-7k``) and the first K held-out views of its default rig (longest side
1024 px), each backend runs in its own fresh process (so peak memory is that backend's alone): one
warm-up view (timed separately: GL context creation, or the reference's ``torch.compile`` when it
kicks in), then every view is rendered and the median is reported. A view's time is the whole
``render(scene, camera)`` call: projection, depth sort, binning/upload, compositing and read-back.
The process CPU time per view is recorded too (the machines are shared and wall time is noisy;
GL work done in llvmpipe threads counts, work in a separate GPU process does not). Peak memory is the child's peak
resident set (and CUDA's peak allocation when on a GPU). A backend that cannot run here (``renderers.gl`` missing, no
EGL) is recorded as not available with the reason.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import statistics
import time

NAME = "render"
HELP = "median seconds per 1024-px view for the GL and reference renderers (incl. sort and upload); peak memory"
BACKENDS = ("gl", "reference")


def add_arguments(parser) -> None:
    parser.add_argument("--scene", default="bonsai-7k", help="scene name or path (default bonsai-7k)")
    parser.add_argument("--views", type=int, default=3, help="held-out views to time (median reported)")
    parser.add_argument("--backends", default=",".join(BACKENDS), help="comma-separated subset of gl,reference")
    parser.add_argument("--device", default=None, help="torch device for the reference (default: cuda if present)")


def _measure(backend: str, scene_name: str, views: int, device) -> dict:
    """Runs in a child process: load, warm up, time each view."""
    import torch

    from harness.benchmarks._common import peak_rss_mb
    from harness.io.datasets import identify
    from harness.io.scenes import load_scene
    from harness.views.rigs import scene_rig

    scene = load_scene(scene_name)
    cams = scene_rig(identify(scene_name), scene).test[:views]
    try:
        from renderers import get_renderer

        renderer = get_renderer(backend, device=device)
    except Exception as err:  # noqa: BLE001 -- ImportError, no EGL display, ...: reported, not fatal
        return {"available": False, "reason": f"{type(err).__name__}: {err}"}
    base_rss = peak_rss_mb()
    try:
        t0 = time.perf_counter()
        renderer.render(scene, cams[0])
        warm = time.perf_counter() - t0
        samples, cpu = [], []
        for cam in cams:
            t0, c0 = time.perf_counter(), time.process_time()
            img = renderer.render(scene, cam)
            samples.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
    finally:
        renderer.close()
    out = {
        "available": True,
        "splats": len(scene),
        "size": [cams[0].width, cams[0].height],
        "views": [c.name for c in cams],
        "first_call_seconds": warm,
        "seconds_per_view": statistics.median(samples),
        "samples": samples,
        "cpu_seconds_per_view": statistics.median(cpu),
        "peak_rss_mb": peak_rss_mb(),
        "rss_after_load_mb": base_rss,
        "mean_pixel": float(img.mean()),
    }
    if torch.cuda.is_available() and backend == "reference":
        out["cuda_peak_alloc_mb"] = torch.cuda.max_memory_allocated() / 2**20
    dev = getattr(renderer, "device", None)
    out["device"] = str(dev) if dev is not None else None
    return out


def run(args) -> int:
    from harness.benchmarks._common import out_dir, write_result
    from harness.core.errors import InputError
    from harness.io.datasets import resolve_scene

    backends = [b.strip() for b in args.backends.split(",") if b.strip()]
    unknown = sorted(set(backends) - set(BACKENDS))
    if unknown or not backends:
        raise InputError("--backends", f"unknown backend(s) {', '.join(unknown) or '(none given)'}; "
                                       f"known: {', '.join(BACKENDS)}")
    if args.views < 1:
        raise InputError("--views", "must be at least 1")
    resolve_scene(args.scene)  # a missing scene is reported here, before any child starts
    folder = out_dir(args)  # created and probed before any work
    results = {}
    ctx = mp.get_context("spawn")
    for backend in backends:
        with cf.ProcessPoolExecutor(max_workers=1, mp_context=ctx) as pool:
            results[backend] = pool.submit(_measure, backend, args.scene, args.views, args.device).result()
        r = results[backend]
        if r["available"]:
            print(f"{backend}: {r['seconds_per_view']:.2f} s/view (median of {len(r['samples'])}; "
                  f"CPU {r['cpu_seconds_per_view']:.2f} s), first call {r['first_call_seconds']:.2f} s, "
                  f"peak RSS {r['peak_rss_mb']:.0f} MiB")
        else:
            print(f"{backend}: not available ({r['reason']})")
    lines = [f"# render benchmark: {args.scene}", "",
             "| backend | size | s/view (median) | CPU s/view | first call s | peak RSS MiB |",
             "|---|---|---|---|---|---|"]
    for backend, r in results.items():
        if r["available"]:
            lines.append(f"| {backend} | {r['size'][0]}×{r['size'][1]} | {r['seconds_per_view']:.2f} | "
                         f"{r['cpu_seconds_per_view']:.2f} | {r['first_call_seconds']:.2f} | {r['peak_rss_mb']:.0f} |")
        else:
            lines.append(f"| {backend} | – | not available: {r['reason']} | – | – | – |")
    write_result(f"render-{args.scene}", {"scene": args.scene, "views": args.views, "backends": results},
                 "\n".join(lines), out=folder)
    return 0
