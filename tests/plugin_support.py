"""Third-party packages for the plugin tests: built and installed the way a user installs one, isolated.

:func:`install` writes a package (its modules and a ``pyproject.toml`` with entry points) into a
folder, then ``pip install --target`` it into another (no network: ``--no-index --no-deps
--no-build-isolation``), never into the project's environment. :func:`harness` runs the command line
with that folder on ``PYTHONPATH`` and ``HARNESS_PLUGINS`` naming only the test's own distributions,
so whatever else is installed on the machine (another metric of the same family, a broken plugin)
cannot change what the test sees.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


def pyproject(dist: str, packages: list[str], entry_points: dict[str, dict[str, str]], version: str = "0.1.0") -> str:
    """A minimal ``pyproject.toml``: setuptools, the packages, the entry points per group."""
    groups = "".join(f'[project.entry-points."{g}"]\n' + "".join(f'{k} = "{v}"\n' for k, v in eps.items())
                     for g, eps in entry_points.items())
    return (f'[build-system]\nrequires = ["setuptools>=68"]\nbuild-backend = "setuptools.build_meta"\n'
            f'[project]\nname = "{dist}"\nversion = "{version}"\n{groups}'
            f'[tool.setuptools]\npackages = {packages!r}\n').replace("'", '"')


def pip_install(src: Path, site: Path) -> Path:
    """``pip install --target site src`` without network; skips the test when it cannot build here."""
    done = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                           "--no-index", "--target", str(site), str(src)], capture_output=True, text=True)
    if done.returncode:
        pytest.skip(f"cannot build a plugin package here: {done.stderr.strip().splitlines()[-1:]}")
    return site


def install(root: Path, dist: str, modules: dict[str, str], entry_points: dict[str, dict[str, str]]) -> Path:
    """Build distribution ``dist`` from ``modules`` (``"pkg/__init__.py": source``) with its entry
    points and install it into ``root/site``; returns the site folder."""
    src = root / f"{dist}-src"
    for rel, code in modules.items():
        (src / rel).parent.mkdir(parents=True, exist_ok=True)
        (src / rel).write_text(textwrap.dedent(code))
    packages = sorted({Path(rel).parts[0] for rel in modules if len(Path(rel).parts) > 1})
    (src / "pyproject.toml").write_text(pyproject(dist, packages, entry_points))
    return pip_install(src, root / "site")


def environment(site: Path, *dists: str) -> dict:
    """The environment of a child process that sees the project, ``site`` and of all installed
    plugins only ``dists``."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), str(site)]), "HARNESS_PLUGINS": ",".join(dists)}


def harness(site: Path, dists, *args, cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    """``python -m harness ARGS`` in ``cwd`` with the plugin site (:func:`environment`)."""
    dists = [dists] if isinstance(dists, str) else list(dists)
    return subprocess.run([sys.executable, "-m", "harness", *args], capture_output=True, text=True,
                          env=environment(site, *dists), cwd=cwd, timeout=timeout)


def project_digest() -> str:
    """A digest of every project file a plugin must not need to touch."""
    import hashlib

    h = hashlib.sha256()
    for root in ("harness", "methods", "renderers", "ctc_configs"):
        for p in sorted((REPO / root).rglob("*")):
            if p.is_file() and "__pycache__" not in p.parts:
                h.update(str(p.relative_to(REPO)).encode() + p.read_bytes())
    h.update((REPO / "pyproject.toml").read_bytes())
    return h.hexdigest()
