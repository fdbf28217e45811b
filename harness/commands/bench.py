"""`harness bench NAME`: run one benchmark (modules in :mod:`harness.benchmarks`, and those installed
packages add through the ``harness.benchmarks`` entry-point group: :func:`benchmarks`).

Each benchmark module defines ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``
(and ``OUT_SUB`` when it writes into a sub-folder of the default ``--out``)
and writes its results (JSON + markdown) into ``--out DIR``, which every benchmark takes: default
``runs/bench`` (git-ignored, so trying a benchmark never rewrites the committed numbers); ``--out
results/bench`` updates the committed results, and the benchmark then says that it did. Speed goals
live here, never in timed tests; ratios are always measured within one run because the machines are
noisy.

Only the chosen benchmark's module is imported (and its parser built); the others are listed by
name and help (:func:`harness.commands.catalog`), so ``harness bench start`` pays for no other
benchmark's imports.
"""

from __future__ import annotations

from harness.commands import Entry, catalog, help_text, plugin_catalog

NAME = "bench"
HELP = "run a benchmark; results into --out (default runs/bench; --out results/bench updates the committed ones)"


def benchmarks() -> list[Entry]:
    """Every benchmark, sorted by name: the modules of :mod:`harness.benchmarks` and the entry points
    of the ``harness.benchmarks`` group (:func:`harness.commands.plugin_catalog`; a built-in's name
    stays the built-in's)."""
    builtin = catalog("harness.benchmarks")
    return sorted(builtin + plugin_catalog("harness.benchmarks", {e.name for e in builtin}), key=lambda e: e.name)


def add_arguments(parser, argv=()) -> None:
    chosen = next((word for word in argv if not word.startswith("-")), None)
    sub = parser.add_subparsers(dest="benchmark", metavar="BENCHMARK", required=True)
    for entry in benchmarks():
        p = sub.add_parser(entry.name, help=help_text(entry.help), description=help_text(entry.help))
        if entry.name == chosen:
            _fill(p, entry.load())


def _fill(p, mod) -> None:
    from harness.benchmarks._common import DEFAULT_OUT

    mod.add_arguments(p)
    p.add_argument("--out", default=None, metavar="DIR",
                   help=help_text(f"folder for the results (default {DEFAULT_OUT}"
                                  f"{'/' + mod.OUT_SUB if hasattr(mod, 'OUT_SUB') else ''}, outside the tracked tree; "
                                  "--out results/bench updates the committed results and says so)"))
    p.set_defaults(_bench=mod.run)


def run(args) -> int:
    return int(args._bench(args) or 0)
