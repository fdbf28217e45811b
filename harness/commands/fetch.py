"""`harness fetch [--scenes] [--weights]`: download and verify the registry scenes and LPIPS weights.

With neither flag both are fetched. Everything is idempotent: present files with the right sha256
are only re-verified.
"""

from __future__ import annotations

NAME = "fetch"
HELP = "download and verify the registry scenes (bonsai-7k, bonsai-7k-mini, luigi) and LPIPS weights"


def add_arguments(parser) -> None:
    parser.add_argument("--scenes", action="store_true", help="fetch the registry scenes")
    parser.add_argument("--weights", action="store_true", help="fetch and convert the LPIPS-VGG weights")


def run(args) -> int:
    both = not (args.scenes or args.weights)
    if args.scenes or both:
        from harness.io.datasets import fetch_scenes

        fetch_scenes(log=print)
    if args.weights or both:
        from harness.metrics.lpips_weights import fetch_weights, weights_path

        before = weights_path().stat().st_mtime_ns if weights_path().is_file() else None
        path = fetch_weights()
        state = "present" if before == path.stat().st_mtime_ns else "fetched and converted"
        print(f"lpips-vgg weights: {state}, sha256 verified ({path})")
    return 0
