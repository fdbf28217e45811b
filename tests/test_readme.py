"""The README is a page for users that holds what it shows: its set-up commands first and as CI runs
them, at most 250 lines, every command line of "Everyday use" accepted by the command's parser, the
`config show` excerpt what the command prints, the render → compare pair runnable as written, and
every relative link of the README and of the documents beside it pointing at a file that exists.
(The Python examples are run by ``tests/test_readme_api.py``.)"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from harness.cli import main, parse_args

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
SETUP = ["./setup.sh && .venv/bin/harness run ctc_configs/default.yaml", "./setup.sh && tests/run"]
MAX_LINES = 250


def section(title: str) -> str:
    text = README.read_text()
    start = text.index(f"\n## {title}")
    end = text.find("\n## ", start + 1)
    return text[start: end if end > 0 else None]


def blocks(text: str, lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", text, re.S)


def everyday_commands() -> list[list[str]]:
    """The argv of every ``harness …`` line of the "Everyday use" block, its comment dropped."""
    (block,) = blocks(section("Everyday use"), "bash")
    return [shlex.split(line, comments=True)[1:] for line in block.splitlines() if line.startswith("harness ")]


def test_setup_commands_come_first_and_are_what_ci_runs():
    lines = README.read_text().splitlines()
    assert lines[2:6] == ["```bash", *SETUP, "```"]
    assert "tests/run" in (ROOT / ".ci" / "run").read_text()


def test_readme_is_short():
    assert len(README.read_text().splitlines()) <= MAX_LINES


def test_everyday_commands_parse():
    """Each line names a command and options it takes (parsed, not run: some run for minutes)."""
    argvs = everyday_commands()
    assert len(argvs) >= 15
    for argv in argvs:
        try:
            args = parse_args(argv)
        except SystemExit as exc:  # argparse's refusal
            pytest.fail(f"README: harness {shlex.join(argv)}: refused by its parser ({exc})")
        assert args.command == argv[0]


def test_every_config_is_described():
    """Each config of ctc_configs/ has its row; the study's research configs are one row."""
    described = section("Configs")
    for config in sorted((ROOT / "ctc_configs").glob("*.yaml")):
        assert f"| `{config.name}` |" in described, f"README, Configs: no row for {config.name}"
    assert "| `study/` |" in described and (ROOT / "ctc_configs" / "study").is_dir()


def _docs_commands() -> list[tuple[str, list[str]]]:
    """``harness …`` lines of the bash blocks of docs/ (plugins.md's are run by tests/test_plugin_docs.py)."""
    found = []
    for doc in sorted((ROOT / "docs").glob("*.md")):
        if doc.name == "plugins.md":
            continue
        for block in blocks(doc.read_text(), "bash"):
            found += [(doc.name, shlex.split(line, comments=True)[1:]) for line in block.splitlines()
                      if line.startswith("harness ")]
    return found


@pytest.mark.parametrize("doc, argv", _docs_commands(), ids=lambda v: v if isinstance(v, str) else " ".join(v[:2]))
def test_docs_commands_parse(doc, argv):
    """The docs' command lines name commands and options that exist (they need a GPU, a cluster or a
    finished run to execute, so they are parsed, not run)."""
    try:
        args = parse_args(argv)
    except SystemExit as exc:
        pytest.fail(f"{doc}: harness {shlex.join(argv)}: refused by its parser ({exc})")
    assert args.command == argv[0]


def test_config_show_excerpt_is_what_it_prints(capsys):
    (excerpt,) = blocks(section("Configs"), "")
    config = re.search(r"# (ctc_configs/\S+\.yaml):\d+", excerpt).group(1)
    assert main(["config", "show", config]) == 0
    printed = capsys.readouterr().out.splitlines()
    for line in excerpt.splitlines():
        if line.strip() and not line.rstrip().endswith(":"):
            assert line in printed, f"README's `config show` line is not printed by it: {line!r}"


@pytest.mark.data
@pytest.mark.gl
@pytest.mark.weights
def test_render_then_compare_as_written(tmp_path, monkeypatch):
    """The README's prune, render, render --format npy and compare lines, as printed."""
    from harness.io.datasets import scene_path
    from harness.metrics import lpips_weights as lw
    from tests.gl_support import require_gl

    if not scene_path("luigi").exists():
        pytest.skip("luigi is not fetched (`harness fetch luigi`)")
    if not lw.weights_available():
        pytest.skip("LPIPS-VGG weights not converted here: run harness fetch --weights")
    require_gl()
    monkeypatch.chdir(tmp_path)
    wanted = [a for a in everyday_commands() if "luigi30.ply" in a or a[0] == "render"
              or (a[0] == "compare" and "views/" in a[1])]
    assert [a[0] for a in wanted] == ["prune", "render", "render", "compare"]
    for argv in wanted:
        assert main(argv) == 0, argv


def _documents() -> list[Path]:
    names = ["README.md", "CONTRIBUTING.md", "CHANGELOG.md", "results/bench/README.md"]
    return [ROOT / n for n in names] + sorted((ROOT / "docs").glob("*.md"))


@pytest.mark.parametrize("doc", _documents(), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_relative_links_resolve(doc):
    text = re.sub(r"```.*?```", "", doc.read_text(), flags=re.S)
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    broken = [t for t in targets if "://" not in t and not (doc.parent / t).exists()]
    assert not broken, f"{doc.name}: links to missing files {broken}"
