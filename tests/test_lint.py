"""The tree passes the linter configured in pyproject.toml (``[tool.ruff]``: line length 120;
pycodestyle errors and warnings, pyflakes, import order). ``ruff format`` is not imposed: the code is
wrapped by hand, and the formatter grows modules by 20-45 % (past the house's ~400 lines per module)
without changing what they say. Skipped with the reason where ruff is not installed
(``pip install -e '.[test]'`` installs it)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


def test_ruff_check_is_clean():
    exe = shutil.which("ruff") or str(Path(sys.executable).parent / "ruff")
    if not Path(exe).is_file():
        pytest.skip("ruff is not installed (pip install -e '.[test]')")
    done = subprocess.run([exe, "check", "--output-format", "concise", "harness", "methods", "renderers", "tests"],
                          cwd=REPO, capture_output=True, text=True)
    assert done.returncode == 0, (done.stdout + done.stderr)[-3000:]
