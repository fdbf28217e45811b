"""Output paths of the commands that write scenes (``prune``, ``convert``), checked before any work.

A bad output leaves nothing behind: the folder must exist and be writable (probed), the name must
not be a folder or a special file, and no output may be an input (or lie inside an input folder).
Stale temporary files of an earlier killed write in that folder are swept first.
"""

from __future__ import annotations

from pathlib import Path

from harness.core.errors import InputError


def check_outputs(outputs: list[Path], inputs: list[Path]) -> None:
    """InputError naming the first unusable output (module docstring)."""
    from harness.io.files import probe_writable, sweep_stale_temps

    for path in outputs:
        if not path.parent.is_dir():
            raise InputError(path, "output folder does not exist")
        if path.is_dir():
            raise InputError(path, "is a folder; give a file name")
        if path.exists() and not path.is_file():
            raise InputError(path, "exists and is not a regular file")
        probe_writable(path.parent, path)  # read-only, /proc ...: refused before any work
        sweep_stale_temps(path.parent)
        for src in inputs:
            if path.resolve() == src.resolve() or (src.is_dir() and src.resolve() in path.resolve().parents):
                raise InputError(path, f"would overwrite the input {src}; choose another output")
