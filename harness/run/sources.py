"""Where a run's scenes come from, checked before any work: :func:`check_sources`.

A scene the config does not mark ``optional: true`` whose files are absent is an error naming it (a
misspelt name gets "did you mean"); an optional one is recorded as a :class:`Skip` with the reason.
A scene file that is there but is not a regular readable file (a FIFO, ``/dev/zero``) is an error
of the config, before the output folder exists, not a skipped scene found by a worker.
"""

from __future__ import annotations

import glob
from dataclasses import dataclass
from pathlib import Path

from harness.run.config import RunConfig, SceneSpec
from harness.run.toolkit import Toolkit


@dataclass
class Skip:
    scene: str
    frame: str
    method: str
    variant: str
    reason: str
    status: str = "skipped"  # or "error": the input exists but cannot be used (bad file, bad split)



def resolve_paths(spec: SceneSpec, toolkit: Toolkit, base: Path) -> tuple[list[tuple[str, Path]], str | None]:
    """[(frame, path)] for a scene, or ([], reason) when its files are absent."""
    if spec.sequence is not None:
        from harness.io.sequences import find_sequence

        root = Path(spec.sequence) if Path(spec.sequence).is_absolute() else base / spec.sequence
        seq, reason = find_sequence(root)
        return ([(p.stem, p) for p in seq.frames], None) if seq else ([], reason)
    if spec.frames is not None:
        pattern = spec.frames if Path(spec.frames).is_absolute() else str(base / spec.frames)
        files = sorted(Path(p) for p in glob.glob(pattern))
        if not files:
            return [], f"no frame files match {spec.frames}"
        return [(p.stem, p) for p in files], None
    src = spec.source
    named = toolkit.resolve_dataset(src)
    if named is not None:
        if not Path(named).exists():
            from harness.io.datasets import missing_reason

            return [], missing_reason(src)
        return [("", Path(named))], None
    path = Path(src) if Path(src).is_absolute() else base / src
    if not path.exists():
        return [], f"file not found: {src}"
    return [("", path)], None


def _looks_like_name(text: str) -> bool:
    """A bare word (``luigii``), not a path (``scenes/x.ply``, ``x.ply``): a misspelt dataset name."""
    return "/" not in text and "\\" not in text and not Path(text).suffix


def _explain(spec: SceneSpec, reason: str, toolkit: Toolkit) -> str:
    """Why a scene cannot be found, with the dataset names close to a misspelt one."""
    if spec.source is not None and toolkit.resolve_dataset(spec.source) is None and _looks_like_name(spec.source):
        from harness.core.suggest import unknown
        from harness.io.datasets import SCENES

        return f"{unknown('scene name', spec.source, list(SCENES))}, and no file of that name in the working folder"
    return reason


def check_sources(config: RunConfig, toolkit: Toolkit, base: Path, *, names_only: bool = False) -> list[Skip]:
    """Resolve every scene of ``config`` before any work: the optional ones whose files are absent
    as skips; any other that cannot be found is an InputError naming each such scene (one line).
    ``names_only`` (``harness plan``, which estimates absent data): only misspelt names fail."""
    from harness.core.errors import InputError

    skips, problems = [], []
    for i, spec in enumerate(config.scenes):
        paths, reason = resolve_paths(spec, toolkit, base)
        reason = reason or cameras_missing(spec, base)
        if reason is None:
            unusable(paths, f"scenes[{i}] {spec.name!r}")
            continue
        if spec.optional:
            skips.append(Skip(spec.name, "", "*", "*", reason))
            continue
        explained = _explain(spec, reason, toolkit)
        if not names_only or explained != reason:
            problems.append(f"scenes[{i}] {spec.name!r}: {explained}")
    if problems:
        raise InputError(config.source_path or "config", "; ".join(problems)
                         + " (mark a scene that may be absent `optional: true` to skip it instead)")
    return skips


def unusable(paths, where: str) -> None:
    """InputError when a scene's file is not a regular readable file (a FIFO, ``/dev/zero``): found
    before any work, not when a worker opens it (a folder is a SOG scene's, read as one later)."""
    import os

    from harness.core.errors import InputError
    from harness.io.safe import check_regular

    for _, path in paths:
        if path.is_dir():
            continue
        try:
            check_regular(path, "scene", "scene file", record=False)
        except InputError as err:
            raise InputError(err.source, f"{where}: {err.problem}") from None
        if not os.access(path, os.R_OK):
            raise InputError(path, f"{where}: cannot read: permission denied")


def cameras_missing(spec: SceneSpec, base: Path) -> str | None:
    if spec.cameras is None:
        return None
    p = Path(spec.cameras.path)
    return None if (p if p.is_absolute() else base / p).exists() else f"cameras not found: {spec.cameras.path}"
