"""Every command's and every benchmark's --help works: it is the first thing a newcomer types."""

from __future__ import annotations

import pytest

from harness.cli import build_parser, main


def _subcommands(parser):
    action = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    return action.choices


@pytest.mark.parametrize("command", sorted(_subcommands(build_parser())))
def test_command_help(command, capsys):
    with pytest.raises(SystemExit) as info:
        main([command, "--help"])
    assert info.value.code == 0 and "usage:" in capsys.readouterr().out


@pytest.mark.parametrize("bench", sorted(_subcommands(_subcommands(build_parser())["bench"])))
def test_benchmark_help(bench, capsys):
    """`harness bench methods --help` used to crash on the "%" of "30 %" in its help text."""
    with pytest.raises(SystemExit) as info:
        main(["bench", bench, "--help"])
    assert info.value.code == 0 and "usage:" in capsys.readouterr().out
