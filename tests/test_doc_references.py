"""User documents and the product's docstrings speak to users: no internal issue numbers, no "wave"
names, no commit hashes of this project.

* ``issue N``, ``issues N`` and ``wave N`` are refused in the README, ``CONTRIBUTING.md``,
  ``CHANGELOG.md``, ``docs/``, ``results/bench/README.md`` and every ``.py`` file of the product
  (``harness/``, ``methods/``, ``renderers/``; ``harness/study/`` is the paper study, not the product).
* A hexadecimal token of 7 to 40 digits with a letter and a figure in it is a commit hash. It is
  refused in those documents and in the product's docstrings, except where the text names the
  commit of another project it follows (:data:`UPSTREAM`: a pin a reader can open), and in the
  study's pre-registration documents (:data:`PREREGISTRATION`), which name the commits their rules
  were fixed in — "the pre-registration commits of a study are named in that study's own document".
  A token after ``~`` is a file name's content hash (``x_y~bd3c9047d681``), not a commit.
"""

from __future__ import annotations

import ast
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

#: the study's own pre-registration documents: the only user documents that name this project's commits
PREREGISTRATION = ("docs/claims.md", "docs/reading.md")

#: commits of other projects the code or the documents follow, with the repository each belongs to
UPSTREAM = {
    "c4a0c1cae5693c5ef5697b62ca2e85af12fce36c": "little-little-point-cloud-group/gscem (mpeg-gsc-metrics)",
    "a601648f8a48": "the PMBB library vendored by gscem",
    "8d6b801": "playcanvas/splat-transform v3.2.0",
    "21715c3": "nianticlabs/spz",
    "eb2fc45": "mkkellogg/GaussianSplats3D",
    "e801512": "the Confident Splatting code of the paper's era",
    "e7343b2": "the Confident Splatting code at its HEAD",
    "b20eca07": "JinchuLi2002/CoR-GS (the bonsai capture's origin)",
}

REFERENCE = re.compile(r"\bissues? [0-9]+|\bwave ?[0-9]", re.I)
HASH = re.compile(r"(?<![0-9A-Za-z_~])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}(?![0-9A-Za-z_])")


def documents() -> list[Path]:
    names = ["README.md", "CONTRIBUTING.md", "CHANGELOG.md", "results/bench/README.md"]
    return [ROOT / n for n in names if (ROOT / n).is_file()] + sorted((ROOT / "docs").glob("**/*.md"))


def product_sources() -> list[Path]:
    files = [p for pkg in ("harness", "methods", "renderers") for p in sorted((ROOT / pkg).rglob("*.py"))]
    return [p for p in files if "study" not in p.relative_to(ROOT).parts]


def docstrings(path: Path) -> list[tuple[int, str]]:
    """(line, text) of the module's, every class's and every function's docstring."""
    tree = ast.parse(path.read_text(), str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) \
                    and isinstance(first.value.value, str):
                found.append((first.lineno, first.value.value))
    return found


def references(text: str) -> list[str]:
    return [m.group() for m in REFERENCE.finditer(text)]


def project_hashes(text: str) -> list[str]:
    """The commit-hash-like tokens of ``text`` that are not an upstream pin."""
    return [m.group() for m in HASH.finditer(text)
            if not any(pin.startswith(m.group()) or m.group().startswith(pin) for pin in UPSTREAM)]


def _rel(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def test_no_issue_or_wave_references_in_documents():
    bad = {_rel(p): references(p.read_text()) for p in documents()}
    assert not {k: v for k, v in bad.items() if v}


def test_no_issue_or_wave_references_in_the_product():
    bad = {_rel(p): references(p.read_text()) for p in product_sources()}
    assert not {k: v for k, v in bad.items() if v}


def test_no_commit_hashes_in_documents():
    bad = {_rel(p): project_hashes(p.read_text()) for p in documents() if _rel(p) not in PREREGISTRATION}
    assert not {k: v for k, v in bad.items() if v}


def test_no_commit_hashes_in_product_docstrings():
    bad = {f"{_rel(p)}:{line}": found for p in product_sources() for line, text in docstrings(p)
           if (found := project_hashes(text))}
    assert not bad


def test_the_exceptions_are_what_they_say():
    """The pre-registration documents exist and name a commit; no upstream pin is a commit of this
    repository (when its history is here to ask)."""
    for name in PREREGISTRATION:
        assert HASH.search((ROOT / name).read_text()), f"{name} names no commit: take it off the list"
    git = subprocess.run(["git", "rev-parse", "--git-dir"], cwd=ROOT, capture_output=True, text=True)
    if git.returncode != 0:
        pytest.skip("no git history here to check the upstream pins against")
    ours = [pin for pin in UPSTREAM if subprocess.run(["git", "cat-file", "-e", f"{pin}^{{commit}}"], cwd=ROOT,
                                                       capture_output=True).returncode == 0]
    assert not ours, f"these 'upstream' pins are commits of this repository: {ours}"


@pytest.mark.parametrize("text, refs, hashes", [
    ("see issue 21 and issues 15", ["issue 21", "issues 15"], []),
    ("before wave 3, the wave3-base tag", ["wave 3", "wave3"], []),
    ("the default from 185f6c2 to now", [], ["185f6c2"]),
    ("rules commit 52c16a642e93ff4ef58e64fb8291c4dbfcd8529a", [], ["52c16a642e93ff4ef58e64fb8291c4dbfcd8529a"]),
    ("gscem @ c4a0c1cae569…, splat-transform @8d6b801", [], []),
    ("x_y~bd3c9047d681, 1234567 splats, the word accede, 0.25", [], []),
])
def test_the_patterns_catch_what_they_must(text, refs, hashes):
    """Planted references are found; upstream pins, name hashes, numbers and hex-looking words are not."""
    assert references(text) == refs and project_hashes(text) == hashes
