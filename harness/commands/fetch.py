"""`harness fetch [NAME ...] [--scenes] [--weights] [--from URL]`: get the named scenes and the LPIPS
weights onto this machine, verified by sha256 (:mod:`harness.io.fetch`).

Without arguments: every named scene, capture and the weights. ``NAME ...`` fetches those scenes
(each with the capture it carries, :mod:`harness.io.capture`) or captures only;
``--scenes`` all scenes, ``--weights`` the weights. Public scenes are copied from the mirror folder
(``HARNESS_SHARED_DATA``, default ``../shared/data``) when it holds them, else downloaded from their
pinned URL (``--from`` replaces the URL's base, e.g. an internal mirror server). Idempotent: present
files with the right sha256 are only re-verified. Every scene is attempted; a scene that cannot be
had is reported on its own line and the exit status is 1.
"""

from __future__ import annotations

from harness.core.errors import InputError

NAME = "fetch"
HELP = ("download (or generate) and verify the named scenes (bonsai-7k, bonsai-7k-mini, luigi, grape-small, playbot; "
        "synth-room, synth-statue), the bonsai "
        "capture (real cameras and photos) and LPIPS weights")


def add_arguments(parser) -> None:
    parser.add_argument("names", nargs="*", metavar="NAME",
                        help="named scenes or captures to fetch (default: all); a scene brings its capture")
    parser.add_argument("--scenes", action="store_true", help="fetch every named scene")
    parser.add_argument("--weights", action="store_true", help="fetch and convert the LPIPS-VGG weights")
    parser.add_argument("--from", dest="base_url", metavar="URL",
                        help="base URL replacing the public scenes' pinned one (a mirror server)")


def run(args) -> int:
    from harness.io.capture import CAPTURES, SCENE_CAPTURES
    from harness.io.datasets import SCENES

    unknown = [n for n in args.names if n not in SCENES and n not in CAPTURES]
    if unknown:
        from harness.core.suggest import unknown as unknown_name

        raise InputError(unknown[0], unknown_name("scene or capture name", unknown[0], [*SCENES, *CAPTURES]))
    everything = not (args.names or args.scenes or args.weights)
    names = [*SCENES, *CAPTURES] if (args.scenes or everything) else list(args.names)
    # a scene brings the capture it was trained from (its real cameras and photos); a capture only
    # brought along that cannot be had is reported but does not fail the command (the `real`
    # protocol skips the scene with that reason until it is fetched)
    asked = set(names)
    names = list(dict.fromkeys(x for n in names for x in (n, SCENE_CAPTURES.get(n)) if x))
    failed = 0
    if names:
        from harness.io.fetch import fetch_capture, fetch_scenes

        for name in names:
            try:
                if name in CAPTURES:
                    fetch_capture(name, log=print, base_url=args.base_url)
                else:
                    fetch_scenes([name], log=print, base_url=args.base_url)
            except InputError as err:
                failed += name in asked
                print(f"{name}: not fetched: {err}")
    if args.weights or everything:
        from harness.metrics.lpips_weights import fetch_weights, weights_path

        before = weights_path().stat().st_mtime_ns if weights_path().is_file() else None
        path = fetch_weights()
        state = "present" if before == path.stat().st_mtime_ns else "fetched and converted"
        print(f"lpips-vgg weights: {state}, sha256 verified ({path})")
    return 1 if failed else 0
