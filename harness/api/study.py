"""A study from Python: :func:`evaluate` runs a config as ``harness run`` does and returns its rows.

:func:`run_study` is ``harness run`` without the printing: it validates the config and resolves
every scene before any work (a misspelt scene, method or metric, or a required scene whose files are
absent, is one :class:`harness.HarnessError` and nothing is written), runs the staged, cached plan,
writes tidy results, contact sheets and the run record, and publishes the tables, plots and
``report.html`` (:func:`harness.report.outputs.publish`). A run that measured nothing replaces
nothing: the folder's earlier results, tables and page stay, and only its record is added.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from harness.core.errors import InputError


@dataclass
class Study:
    """What a study produced: ``frame`` (the tidy rows, a pandas DataFrame), the output folder, the
    summary lines ``harness run`` prints, the tables' warnings, the count of table/plot files written,
    the stage errors (a failed stage is a row with status "error"), whether anything was measured,
    and the tables' notes (tables made for some held-out view protocols only)."""

    frame: object
    out_dir: Path
    summary: list[str]
    warnings: list[str] = field(default_factory=list)
    written: int = 0
    errors: list[str] = field(default_factory=list)
    measured: bool = True
    notes: list[str] = field(default_factory=list)


def _config(config_or_path):
    """A validated :class:`harness.run.config.RunConfig` from a YAML path, a mapping (the YAML's
    content) or a config already loaded."""
    from harness.run.config import RunConfig, load_config, parse_config

    if isinstance(config_or_path, RunConfig):
        return config_or_path
    if isinstance(config_or_path, (str, Path)):
        return load_config(config_or_path)
    if isinstance(config_or_path, dict):
        return parse_config(config_or_path, "<config>")
    raise InputError("config", f"expected a YAML path, a mapping or a RunConfig, got {type(config_or_path).__name__}")


def executor_spec(spec, name: str | None, address: str | None):
    """The config's ``executor`` with ``executor`` / ``address`` applied (an address means Ray)."""
    import dataclasses

    if address is not None and name == "local":
        raise InputError("address", "is a Ray cluster address; it needs the ray executor, not local")
    if name is None and address is not None:
        name = "ray"
    if name is not None and name not in ("local", "ray"):
        raise InputError("executor", f"must be local or ray, got {name!r}")
    if name is not None and name != spec.name:
        spec = dataclasses.replace(spec, name=name, address=None) if name == "local" else \
            dataclasses.replace(spec, name=name)
    if address is not None:
        spec = dataclasses.replace(spec, address=address)
    return spec


def run_study(config_or_path, *, out=None, executor: str | None = None, address: str | None = None,
              workers: int | None = None, threads: int | None = None, cache=None, force: bool = False,
              console=None, argv=None) -> Study:
    """Run a study (module docstring). ``executor`` None: the config's; ``console``: a rich Console
    for progress and messages (default: stderr); ``argv``: what the run record says ran it."""
    from harness.core.arguments import optional, whole
    from harness.core.devices import check_device
    from harness.core.paths import cache_dir
    from harness.io.files import check_output_folder, make_output_folder, sweep_stale_temps
    from harness.io.owned import OwnedFolder
    from harness.run.cache import is_url
    from harness.run.executors import preflight
    from harness.run.finish import PUBLISHED
    from harness.run.protocol_views import check_protocols
    from harness.run.sources import check_sources
    from harness.run.toolkit import Toolkit

    workers = optional(whole, workers, "workers", 1, 256)  # the arguments first, then the config
    threads = optional(whole, threads, "threads", 1, 1024)
    config = _config(config_or_path)
    check_protocols(config, Path.cwd())  # a bad capture: one line, before any output
    workers = config.workers if workers is None else workers
    spec = executor_spec(config.executor, executor, address)
    preflight(spec, workers, cache)  # before the output folder: a bad cache URL or Ray address
    if spec.address is None:  # on a cluster the nodes' devices count (checked when it is joined)
        check_device(config.protocol.device, f"{config.source_path}: protocol.device")
    check_sources(config, Toolkit(), Path.cwd())  # a misspelt or absent required scene: before any work
    out_dir = Path(out or config.output)
    check_output_folder(out_dir, "out" if out else f"{config.source_path}: output")
    cache = str(cache) if cache is not None else None
    if cache and is_url(cache) and not cache.startswith("file://"):
        cache_root = cache  # an fsspec URL: its entries are PUT one by one (harness.run.cache)
    else:
        cache_root = make_output_folder(Path(cache.removeprefix("file://")) if cache else cache_dir() / "stages",
                                        "cache" if cache else "stage cache").absolute()
    with OwnedFolder(out_dir, f"harness run {config.source_path}", "out" if out else f"{config.source_path}: output",
                     owns=PUBLISHED) as folder:
        sweep_stale_temps(out_dir, recursive=True)
        return _run(config, folder, cache_root, spec, workers, threads, force, console, argv)


def _run(config, folder, cache_root, spec, workers, threads, force, console, argv) -> Study:
    """The run itself, once ``folder`` (:class:`harness.io.owned.OwnedFolder`) is held."""
    from rich.console import Console

    from harness.run.executors import make_executor
    from harness.run.finish import finish_run
    from harness.run.progress import StageProgress
    from harness.run.runner import Runner

    out_dir = folder.path
    console = console or Console(stderr=True, soft_wrap=True)
    log = lambda m: console.print(f"[yellow]{m}[/]")  # noqa: E731
    where = f"{workers} worker(s)" if spec.name == "local" else \
        f"Ray ({'a local cluster of ' + str(workers) + ' worker(s)' if spec.address is None else spec.address})"
    console.print(f"[bold]harness run[/] {config.name}: {len(config.scenes)} scenes, "
                  f"{len(config.methods)} method variants, {where} -> {out_dir}")
    with make_executor(spec, workers, device=config.protocol.device, cache_location=str(cache_root), threads=threads,
                       log=log) as pool, StageProgress(console) as progress:
        runner = Runner(config, out_dir=out_dir, cache_root=cache_root, workers=workers, force=force,
                        progress=progress, log=log, base_dir=Path.cwd(), executor=pool)
        result = runner.run()
    done = finish_run(folder, config, runner, result, workers=workers, cache_root=cache_root, argv=argv)
    return Study(done.frame, out_dir, done.summary, warnings=done.warnings, written=done.written,
                 errors=list(result.errors), measured=done.measured, notes=done.notes)


def evaluate(config_or_path, out=None, executor: str | None = "local", **options):
    """Run a study (a YAML config path, its content as a mapping, or a loaded config) like ``harness
    run``, writing everything into ``out`` (default: the config's ``output``), and return its rows:
    a pandas DataFrame, one row per scene × method × ratio × view × protocol (``status`` ok, skipped
    or error). ``executor``: "local" (a process pool), "ray", or None for the config's own;
    ``options``: ``workers``, ``threads``, ``cache``, ``force``, ``address`` as for ``harness run``."""
    return run_study(config_or_path, out=out, executor=executor, **options).frame
