"""`harness run CONFIG [--workers N] [--threads T] [--executor local|ray] [--address A] [--out DIR] [--force] [--cache DIR|URL]`:
the CTC-style evaluation.

Reads and validates the YAML config (:mod:`harness.run.config`) and resolves every scene before any
work (:func:`harness.run.plan.check_sources`): a misspelt scene, method or metric, or a required
scene whose files are absent, is one line (with "did you mean") and exit status 2, and nothing is
written; scenes marked ``optional: true`` whose files are absent are skipped with a message. Then
it runs the staged, cached plan (:mod:`harness.run.runner`), writes tidy results, contact sheets and
the run record (``run.json``, kept per run under ``records/``), and publishes the tables, plots and
``report.html`` (:func:`harness.report.outputs.publish`, the same function as `harness tables` and
`harness report`), printing a summary saying where everything is. A stage that fails on some scene
is recorded in the results and run.json and makes the exit status 1. A table or plot of the config
that these results cannot make is a ``warning:`` line of the summary naming what is missing (the
exit status stays 0: the measurements are complete).

A run that measured nothing (every scene optional and absent, or every stage failed) replaces
nothing: the earlier results, tables and page of the folder stay as they were, and only its record
is added under ``records/``.
"""

from __future__ import annotations

import sys
from pathlib import Path

NAME = "run"
HELP = "evaluate pruning methods on scenes per a YAML config (cached, resumable)"


def add_arguments(parser) -> None:
    parser.add_argument("config", help="run config (YAML), e.g. ctc_configs/default.yaml")
    parser.add_argument("--workers", type=int, default=None, help="process pool size (default: the config's)")
    parser.add_argument("--threads", type=int, default=None,
                        help="threads (CPUs) per worker (default: cores // workers; with Ray: the config's "
                             "executor.cpus_per_task, else the same)")
    parser.add_argument("--out", default=None, help="output folder (default: the config's `output`)")
    parser.add_argument("--force", action="store_true", help="recompute every stage, ignoring cached results")
    parser.add_argument("--cache", default=None,
                        help="stage cache folder or fsspec URL such as s3://bucket/prefix (default: <harness "
                             "cache>/stages, shared by all runs); with Ray on several nodes, a location every node reaches")
    parser.add_argument("--executor", choices=("local", "ray"), default=None,
                        help="where the work runs: local process pool (default) or Ray (default: the config's `executor`)")
    parser.add_argument("--address", default=None,
                        help="Ray cluster to use: auto, HOST:PORT or ray://HOST:10001 (implies --executor ray; "
                             "without it Ray starts a local cluster of --workers workers on this machine)")


def run(args) -> int:
    from rich.console import Console

    from harness.core.errors import InputError
    from harness.core.paths import cache_dir
    from harness.run.config import load_config
    from harness.run.finish import finish_run
    from harness.run.progress import StageProgress
    from harness.run.runner import Runner

    config = load_config(args.config)
    from harness.run.captured import check_captures

    check_captures(config, Path.cwd())  # a bad capture: one line, exit 2, before any output
    workers = args.workers if args.workers is not None else config.workers
    if not 1 <= workers <= 256:
        raise InputError("--workers", f"must be 1..256, got {workers}")
    if args.threads is not None and not 1 <= args.threads <= 1024:
        raise InputError("--threads", f"must be 1..1024, got {args.threads}")
    spec = executor_spec(config.executor, args.executor, args.address)
    from harness.run.executors import preflight

    preflight(spec, workers, args.cache)  # before the output folder: a bad cache URL or Ray address
    from harness.core.devices import check_device
    from harness.io.files import make_output_folder, sweep_stale_temps
    from harness.run.cache import is_url
    from harness.run.executors import make_executor

    if spec.address is None:  # on a cluster the nodes' devices count (checked when it is joined)
        check_device(config.protocol.device, f"{args.config}: protocol.device")
    from harness.run.plan import check_sources
    from harness.run.toolkit import Toolkit

    check_sources(config, Toolkit(), Path.cwd())  # a misspelt or absent required scene: before any work
    out_dir = make_output_folder(Path(args.out or config.output), "--out" if args.out else f"{args.config}: output")
    if args.cache and is_url(args.cache) and not args.cache.startswith("file://"):
        cache_root = args.cache  # an fsspec URL: its entries are PUT one by one (harness.run.cache)
    else:
        cache_root = make_output_folder(Path(args.cache.removeprefix("file://")) if args.cache else cache_dir() / "stages",
                                        "--cache" if args.cache else "stage cache").absolute()
    sweep_stale_temps(out_dir, recursive=True)
    console = Console(stderr=True, soft_wrap=True)
    where = f"{workers} worker(s)" if spec.name == "local" else \
        f"Ray ({'a local cluster of ' + str(workers) + ' worker(s)' if spec.address is None else spec.address})"
    console.print(f"[bold]harness run[/] {config.name}: {len(config.scenes)} scenes, "
                  f"{len(config.methods)} method variants, {where} -> {out_dir}")
    with make_executor(spec, workers, device=config.protocol.device, cache_location=str(cache_root), threads=args.threads,
                       log=lambda m: console.print(f"[yellow]{m}[/]")) as executor, StageProgress(console) as progress:
        runner = Runner(config, out_dir=out_dir, cache_root=cache_root, workers=workers, force=args.force,
                        progress=progress, log=lambda m: console.print(f"[yellow]{m}[/]"),
                        base_dir=Path.cwd(), executor=executor)
        result = runner.run()
    done = finish_run(out_dir, config, runner, result, workers=workers, cache_root=cache_root, argv=sys.argv[1:])
    for line in done.summary:
        print(line)
    if done.measured:
        for line in done.warnings:  # what the config asked for and these results cannot show
            print(f"warning: {line}")
        print(f"wrote {done.written} table/plot files")
    return 1 if result.errors else 0


def executor_spec(spec, name: str | None, address: str | None):
    """The config's ``executor`` with ``--executor`` / ``--address`` applied (``--address`` means Ray)."""
    import dataclasses

    from harness.core.errors import InputError

    if address is not None and name == "local":
        raise InputError("--address", "is a Ray cluster address; it goes with --executor ray")
    if name is None and address is not None:
        name = "ray"
    if name is not None and name != spec.name:
        spec = dataclasses.replace(spec, name=name, address=None) if name == "local" else \
            dataclasses.replace(spec, name=name)
    if address is not None:
        spec = dataclasses.replace(spec, address=address)
    return spec
