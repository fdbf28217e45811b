"""`harness bench NAME`: run one benchmark (modules in :mod:`harness.benchmarks`).

Each benchmark module defines ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``
(and ``OUT_SUB`` when it writes into a sub-folder of the default ``--out``)
and writes its results (JSON + markdown) into ``--out DIR``, which every benchmark takes: default
``runs/bench`` (git-ignored, so trying a benchmark never rewrites the committed numbers); ``--out
results/bench`` updates the committed results, and the benchmark then says that it did. Speed goals
live here, never in timed tests; ratios are always measured within one run because the machines are
noisy.
"""

from __future__ import annotations

import importlib
import pkgutil

from harness.benchmarks._common import DEFAULT_OUT
from harness.commands import help_text

NAME = "bench"
HELP = "run a benchmark; results into --out (default runs/bench; --out results/bench updates the committed ones)"


def _modules():
    import harness.benchmarks as pkg

    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda m: m.name):
        if not info.name.startswith("_"):
            yield importlib.import_module(f"harness.benchmarks.{info.name}")


def add_arguments(parser) -> None:
    sub = parser.add_subparsers(dest="benchmark", metavar="BENCHMARK", required=True)
    for mod in _modules():
        p = sub.add_parser(mod.NAME, help=help_text(mod.HELP), description=help_text(mod.HELP))
        mod.add_arguments(p)
        p.add_argument("--out", default=None, metavar="DIR",
                       help=help_text(f"folder for the results (default {DEFAULT_OUT}"
                                      f"{'/' + mod.OUT_SUB if hasattr(mod, 'OUT_SUB') else ''}, outside the tracked tree; "
                                      "--out results/bench updates the committed results and says so)"))
        p.set_defaults(_bench=mod.run)


def run(args) -> int:
    return int(args._bench(args) or 0)
