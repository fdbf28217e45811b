"""`harness info SCENE [--json] [--lod N|all] [--drop-nonfinite]`: what a scene holds.

``--json`` prints strict JSON: a statistic that is not finite (e.g. the mean scale of a scene with
an overflowing log-scale) is ``null`` (:mod:`harness.core.jsonout`). The facts are
:func:`harness.api.info` (``harness.info`` in Python); this module prints them."""

from __future__ import annotations

import sys

NAME = "info"
HELP = "describe a scene (by path or name): splat count, SH degree, bounding box, opacity/scale stats, memory"


def add_arguments(parser) -> None:
    parser.add_argument("scene", help="path (.ply, .compressed.ply, .spz, .ksplat, .splat, SOG folder/meta.json/.sog) "
                                      "or a scene name")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--lod", type=lod_arg, default=None, help="SOG LOD level (default 0) or 'all'")
    parser.add_argument("--drop-nonfinite", action="store_true",
                        help="drop splats with NaN/inf values (reports how many) instead of failing")


def lod_arg(text: str):
    """argparse type for ``--lod``: a level number or 'all'."""
    if text == "all":
        return text
    try:
        return int(text)
    except ValueError:
        raise __import__("argparse").ArgumentTypeError(f"expected a level number or 'all', got {text!r}") from None


def _fmt_stats(s: dict) -> str:
    if s["min"] is None:
        return "n/a"
    return f"min {s['min']:.4g}  median {s['median']:.4g}  mean {s['mean']:.4g}  max {s['max']:.4g}"


def run(args) -> int:
    from harness.api.scenes import info as describe

    info = describe(args.scene, lod=args.lod, drop_nonfinite=args.drop_nonfinite)
    if info["dropped_nonfinite"]:
        print(f"harness: {info['path']}: dropped {info['dropped_nonfinite']} splats with NaN/inf values",
              file=sys.stderr)
    if args.json:  # non-finite statistics (an overflowing scale) are null: always valid JSON
        from harness.core.jsonout import dumps

        print(dumps(info))
        return 0
    lo, hi = info["bbox_min"], info["bbox_max"]
    lines = [
        f"scene       {info['path']}",
        f"format      {info['format_name']}" + (f" (LOD {info['lod']})" if info["lod"] is not None else ""),
        f"splats      {info['splats']:,}",
        f"SH degree   {info['sh_degree']}",
        f"bbox min    {lo[0]:.4g} {lo[1]:.4g} {lo[2]:.4g}",
        f"bbox max    {hi[0]:.4g} {hi[1]:.4g} {hi[2]:.4g}",
        f"diagonal    {info['bbox_diagonal']:.4g}",
        f"opacity     {_fmt_stats(info['opacity'])}",
        f"scale       {_fmt_stats(info['scale'])}",
        f"extra       {', '.join(info['extra_properties']) or '-'}",
        f"memory      {info['memory_bytes'] / 2**20:.1f} MiB in memory, {info['file_bytes'] / 2**20:.1f} MiB on disk",
    ]
    print("\n".join(lines))
    return 0
