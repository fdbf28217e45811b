"""`harness convert IN OUT`: the same splats in another format, chosen by OUT's name.

Reads anything the harness reads (a path or a scene name; ``--lod`` picks a SOG LOD level) and
writes ``.ply`` (lossless: every property, extra properties and header comments kept),
``.compressed.ply``, ``.splat``, ``.spz`` (``--spz-version 2|3|4``, default 4) or PlayCanvas SOG
(``.sog``: one zip; ``meta.json``: the JSON and its WebP textures in that folder), the lossy ones
saying what this scene loses in them, by the writers of :mod:`harness.io.writers`, which ``prune``
uses too. Outputs (every file a SOG folder set replaces) are checked before anything is read
(format from the name, folder, not an input), written atomically; inputs are never modified.
Prints the formats, splat counts, sizes (all of a scene's files), what the output loses and the
seconds (``--json``: one object). Rows may be reordered (compressed.ply and SOG are written in
Morton order).
"""

from __future__ import annotations

import time
from pathlib import Path

NAME = "convert"
HELP = "write a scene in another format (.ply, .compressed.ply, .splat, .spz, .sog), chosen by the output's name"


def add_arguments(parser) -> None:
    from harness.commands.info import lod_arg
    from harness.io.spz_write import DEFAULT_VERSION, VERSIONS
    from harness.io.writers import endings

    parser.add_argument("input", help="scene file (.ply, .compressed.ply, .spz, .ksplat, .splat, SOG) or a scene name")
    parser.add_argument("output", help=f"the converted scene; its name picks the format: {', '.join(endings())}")
    parser.add_argument("--spz-version", type=int, choices=VERSIONS, default=DEFAULT_VERSION,
                        help=f"spz version to write (default {DEFAULT_VERSION}, the current one; 2 and 3 are "
                             "gzip files older readers take)")
    parser.add_argument("--lod", type=lod_arg, default=None, help="SOG LOD level to read (default 0) or 'all'")
    parser.add_argument("--drop-nonfinite", action="store_true",
                        help="drop splats with NaN/inf values (reports how many) instead of failing")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def _size(path: Path) -> int:
    from harness.io.scenes import scene_files

    return sum(f.stat().st_size for f in scene_files(path))


def run(args) -> int:
    from harness.api.scenes import check_outputs
    from harness.io.datasets import resolve_scene
    from harness.io.scenes import read_scene, write_scene
    from harness.io.writers import writer_for

    out = Path(args.output)
    writer = writer_for(out)
    check_outputs(writer.files(out), [resolve_scene(args.input)])
    seconds = {}
    t0 = time.perf_counter()
    loaded = read_scene(args.input, lod=args.lod, drop_nonfinite=args.drop_nonfinite)
    seconds["read"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    write_scene(loaded.scene, out, spz_version=args.spz_version)
    seconds["write"] = time.perf_counter() - t0
    version = f" v{args.spz_version}" if writer.ending == ".spz" else ""
    loses = writer.loses(loaded.scene)
    report = {"input": {"path": str(loaded.path), "format": loaded.format_name, "splats": len(loaded.scene),
                        "bytes": _size(loaded.path)},
              "output": {"path": str(out), "format": writer.label + version, "splats": len(loaded.scene),
                         "bytes": _size(out)},
              "lossless": not loses, "loses": loses or None,
              "dropped_nonfinite": loaded.dropped_nonfinite, "seconds": seconds}
    if args.json:
        from harness.core.jsonout import dumps

        print(dumps(report))
        return 0
    i, o = report["input"], report["output"]
    print(f"{i['path']} ({i['format']}, {i['splats']:,} splats, {i['bytes']:,} bytes)")
    print(f"  -> {o['path']} ({o['format']}, {o['splats']:,} splats, {o['bytes']:,} bytes)")
    print(f"  {'lossless' if report['lossless'] else 'lossy: ' + loses}")
    if loaded.dropped_nonfinite:
        print(f"  dropped {loaded.dropped_nonfinite:,} splats with NaN/inf values")
    print("  " + ", ".join(f"{k} {v:.3f} s" for k, v in seconds.items()))
    return 0
