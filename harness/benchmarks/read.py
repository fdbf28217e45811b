"""`harness bench read`: scene read/write speed and memory.

Measures, for one scene (default ``bonsai-7k``, the largest registry scene): the median wall time of
``load_scene`` (read + validation), the peak memory the read allocates (tracemalloc, which numpy
reports its buffers to, so it is independent of whatever else the process holds) and the resident
set afterwards; then the time to write it as a binary ``.ply`` and to read that ``.ply`` back.
The PlayCanvas SOG scene ``playbot`` (LOD 0) is timed as well when present.
"""

from __future__ import annotations

import gc
import tempfile
import tracemalloc
from pathlib import Path

NAME = "read"
HELP = "time reading bonsai-7k (.splat), writing/reading it as .ply, and reading playbot (SOG); peak memory"


def add_arguments(parser) -> None:
    parser.add_argument("--scene", default="bonsai-7k", help="scene name or path (default bonsai-7k)")
    parser.add_argument("--repeats", type=int, default=3, help="timed repetitions per step (median reported)")


def _peak_alloc_mb(fn) -> float:
    gc.collect()
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


def run(args) -> int:
    from harness.benchmarks._common import median_time, out_dir, peak_rss_mb, write_result
    from harness.core.errors import InputError
    from harness.io.datasets import resolve_scene
    from harness.io.scenes import load_scene, write_scene

    folder = out_dir(args)  # created and probed before any work
    path = resolve_scene(args.scene)
    scene = load_scene(path)
    rows: dict[str, dict] = {}
    t, samples = median_time(lambda: load_scene(path), args.repeats)
    rows["read"] = {"seconds": t, "samples": samples, "peak_alloc_mb": _peak_alloc_mb(lambda: load_scene(path))}
    with tempfile.TemporaryDirectory() as tmp:
        ply = Path(tmp) / "scene.ply"
        t, samples = median_time(lambda: write_scene(scene, ply), args.repeats)
        rows["write_ply"] = {
            "seconds": t,
            "samples": samples,
            "peak_alloc_mb": _peak_alloc_mb(lambda: write_scene(scene, ply)),
            "file_mb": ply.stat().st_size / 2**20,
        }
        t, samples = median_time(lambda: load_scene(ply), args.repeats)
        rows["read_ply"] = {"seconds": t, "samples": samples, "peak_alloc_mb": _peak_alloc_mb(lambda: load_scene(ply))}
    try:
        sog = resolve_scene("playbot")
    except InputError:  # the shared data folder is optional
        sog = None
    if sog is not None:
        t, samples = median_time(lambda: load_scene(sog), args.repeats)
        rows["read_sog_playbot_lod0"] = {"seconds": t, "samples": samples,
                                         "peak_alloc_mb": _peak_alloc_mb(lambda: load_scene(sog))}
    payload = {
        "scene": str(path),
        "splats": len(scene),
        "sh_degree": scene.sh_degree,
        "scene_mb": scene.nbytes / 2**20,
        "file_mb": path.stat().st_size / 2**20 if path.is_file() else None,
        "steps": rows,
        "process_peak_rss_mb": peak_rss_mb(),
        "repeats": args.repeats,
    }
    title = (f"# read benchmark: {path.name} ({len(scene):,} splats, SH {scene.sh_degree}, "
             f"{payload['scene_mb']:.1f} MiB in memory)")
    md = [title, "",
          "| step | median s | samples s | peak alloc MiB |", "|---|---|---|---|"]
    for step, r in rows.items():
        md.append(f"| {step} | {r['seconds']:.3f} | {', '.join(f'{s:.3f}' for s in r['samples'])} | "
                  f"{r['peak_alloc_mb']:.0f} |")
    md += ["", f"process peak RSS: {payload['process_peak_rss_mb']:.0f} MiB"]
    write_result(NAME, payload, "\n".join(md), out=folder)
    print("\n".join(md))
    return 0
