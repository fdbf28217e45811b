"""The README's Python example runs as written and prints what the README shows (doctest)."""

from __future__ import annotations

import doctest
import re
from pathlib import Path

import pytest

from harness.io.datasets import scene_path
from harness.metrics import lpips_weights as lw
from tests.gl_support import require_gl

README = Path(__file__).resolve().parent.parent / "README.md"

pytestmark = [pytest.mark.data, pytest.mark.gl, pytest.mark.weights]


def example() -> str:
    """The ```python blocks of the README's "From Python" section."""
    text = README.read_text()
    section = text[text.index("## From Python"):]
    section = section[: section.index("\n## ", 1)]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert blocks and ">>> import harness" in blocks[0]
    return "\n".join(blocks)


def test_the_readme_example(tmp_path, monkeypatch):
    if not scene_path("luigi").exists():
        pytest.skip("luigi is not fetched (`harness fetch luigi`)")
    if not lw.weights_available():
        pytest.skip("LPIPS-VGG weights not converted here: run harness fetch --weights")
    require_gl()
    monkeypatch.chdir(tmp_path)  # the example writes luigi30.ply and study/ into the working folder
    test = doctest.DocTestParser().get_doctest(example(), {}, "README.md: From Python", str(README), 0)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    runner.run(test)
    assert runner.summarize(verbose=False).failed == 0
    assert (tmp_path / "luigi30.ply").is_file() and (tmp_path / "study" / "results.parquet").is_file()


def test_the_example_is_checked():
    """A wrong line in the example fails: the runner compares every printed value."""
    test = doctest.DocTestParser().get_doctest(">>> 1 + 1\n3\n", {}, "planted", None, 0)
    runner = doctest.DocTestRunner()
    runner.run(test, out=lambda _: None)
    assert runner.summarize(verbose=False).failed == 1
