"""The README's Python examples run as written and print what the README shows (doctest): "From
Python" in this process, "Plugins" in a fresh interpreter (its registrations must not reach the
registries the other tests read)."""

from __future__ import annotations

import doctest
import re
import subprocess
import sys
from pathlib import Path

import pytest

from harness.io.datasets import scene_path
from harness.metrics import lpips_weights as lw
from tests.gl_support import require_gl

README = Path(__file__).resolve().parent.parent / "README.md"

pytestmark = [pytest.mark.data, pytest.mark.gl, pytest.mark.weights]


def example(title: str = "From Python") -> str:
    """The ```python blocks of the README's section ``title``."""
    text = README.read_text()
    section = text[text.index(f"## {title}"):]
    section = section[: section.index("\n## ", 1)]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert blocks and "import" in blocks[0]
    return "\n".join(blocks)


def _needs_luigi_and_weights():
    if not scene_path("luigi").exists():
        pytest.skip("luigi is not fetched (`harness fetch luigi`)")
    if not lw.weights_available():
        pytest.skip("LPIPS-VGG weights not converted here: run harness fetch --weights")


def test_the_readme_example(tmp_path, monkeypatch):
    _needs_luigi_and_weights()
    require_gl()
    monkeypatch.chdir(tmp_path)  # the example writes luigi30.ply and study/ into the working folder
    test = doctest.DocTestParser().get_doctest(example(), {}, "README.md: From Python", str(README), 0)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    runner.run(test)
    assert runner.summarize(verbose=False).failed == 0
    assert (tmp_path / "luigi30.ply").is_file() and (tmp_path / "study" / "results.parquet").is_file()


PLUGIN_RUNNER = """
import doctest, sys
text = sys.stdin.read()
test = doctest.DocTestParser().get_doctest(text, {"__name__": "__main__"}, "README.md: Plugins", "README.md", 0)
runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
runner.run(test)
sys.exit(1 if runner.summarize(verbose=False).failed or not test.examples else 0)
"""


def test_the_readme_plugin_example(tmp_path):
    """One registration of each kind, then a study over them, as typed into an interactive session
    (``__name__`` is ``__main__`` there: the functions it defines belong to that module)."""
    _needs_luigi_and_weights()
    require_gl()
    done = subprocess.run([sys.executable, "-c", PLUGIN_RUNNER], input=example("Plugins"), cwd=tmp_path,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr


def test_the_example_is_checked():
    """A wrong line in the example fails: the runner compares every printed value."""
    test = doctest.DocTestParser().get_doctest(">>> 1 + 1\n3\n", {}, "planted", None, 0)
    runner = doctest.DocTestRunner()
    runner.run(test, out=lambda _: None)
    assert runner.summarize(verbose=False).failed == 1
