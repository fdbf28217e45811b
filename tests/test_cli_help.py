"""Every command's and every benchmark's --help works: it is the first thing a newcomer types."""

from __future__ import annotations

import pytest

from harness.cli import build_parser, main
from harness.commands import catalog
from harness.commands.bench import benchmarks

COMMANDS = [e.name for e in catalog("harness.commands")]
BENCHMARKS = [e.name for e in benchmarks()]


def _subcommands(parser):
    action = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    return action.choices


def test_every_command_and_benchmark_is_listed():
    """The catalog reads NAME and HELP from the sources: the same as the modules hold, each named
    after its file (so `harness NAME` finds it), and the top-level help lists them all."""
    import importlib

    assert {"prune", "info", "render", "compare", "run", "bench"} <= set(COMMANDS) and "prune" in BENCHMARKS
    for entry in catalog("harness.commands") + benchmarks():
        mod = importlib.import_module(entry.module)
        assert (entry.name, entry.help) == (mod.NAME, mod.HELP) and entry.module.endswith("." + entry.name)
    assert {"reading", "virtualrig", "tradeoff"} <= set(BENCHMARKS)  # the study's, through its entry points
    assert sorted(_subcommands(build_parser())) == sorted(COMMANDS)


@pytest.mark.parametrize("command", COMMANDS)
def test_command_help(command, capsys):
    with pytest.raises(SystemExit) as info:
        main([command, "--help"])
    assert info.value.code == 0 and "usage:" in capsys.readouterr().out


@pytest.mark.parametrize("bench", BENCHMARKS)
def test_benchmark_help(bench, capsys):
    """`harness bench methods --help` used to crash on the "%" of "30 %" in its help text."""
    with pytest.raises(SystemExit) as info:
        main(["bench", bench, "--help"])
    assert info.value.code == 0 and "usage:" in capsys.readouterr().out


def _usage_error(capsys, *argv) -> str:
    with pytest.raises(SystemExit) as info:
        main(list(argv))
    assert info.value.code == 2
    return capsys.readouterr().err


def _help(capsys, *argv) -> str:
    with pytest.raises(SystemExit) as info:
        main([*argv, "--help"])
    assert info.value.code == 0
    return capsys.readouterr().out


def test_a_typo_gets_the_commands_usage_and_a_suggestion(capsys):
    err = _usage_error(capsys, "prune", "a.ply", "b.ply", "--ratio", "0.3", "--voxl", "1")
    assert err.startswith("usage: harness prune ") and "did you mean '--voxel'?" in err
    assert "usage: harness [-h]" not in err
    err = _usage_error(capsys, "prun", "a.ply")
    assert "did you mean 'prune'" in err
    err = _usage_error(capsys, "score", "a.ply", "b.ply", "--renderer", "glx")
    assert err.startswith("usage: harness score ") and "did you mean 'gl'?" in err


def test_another_pruners_flag_names_its_owners(capsys):
    err = _usage_error(capsys, "prune", "a.ply", "b.ply", "--ratio", "0.3", "--method", "random", "--voxel", "1")
    owners = err.split("--voxel: a parameter of ", 1)[1]  # other tests' pruners may own one too
    assert "betadesc" in owners.split(", not of")[0] and "not of random" in owners


def test_prune_help_shows_the_chosen_pruners_flags_only(capsys):
    default = _help(capsys, "prune")
    assert "betadesc parameters" in default and "--voxel" in default and "--iterations" not in default
    assert "INRIA .ply" not in default and ".spz" in default and ".compressed.ply" in default
    lightgs = _help(capsys, "prune", "--method", "lightgs")
    assert "lightgs parameters" in lightgs and "--train-longest-side" in lightgs and "--voxel" not in lightgs
    assert len(default.splitlines()) < 150 and len(lightgs.splitlines()) < 50  # every pruner's: 178+ lines


def test_names_get_did_you_mean(tmp_path, capsys):
    assert main(["info", "luigii"]) == 2
    assert "did you mean 'luigi'?" in capsys.readouterr().err
    assert main(["prune", "luigi", str(tmp_path / "o.ply"), "--ratio", "0.3", "--method", "lightgss"]) == 2
    assert "did you mean 'lightgs'?" in capsys.readouterr().err
    assert main(["prune", "luigi", str(tmp_path / "o.ply"), "--ratio", "0.3", "--param", "voxl=1"]) == 2
    assert "did you mean 'voxel'?" in capsys.readouterr().err
    assert not (tmp_path / "o.ply").exists()


def _long_options(argv) -> list[str]:
    """The long options of the parser ``harness ARGV`` is parsed by (--help only when it has no other)."""
    from harness.cli import _command_module, command_parser

    parser = command_parser(_command_module(argv[0]), argv[1:])
    if len(argv) > 1:  # a benchmark: its own sub-parser
        parser = _subcommands(parser)[argv[1]]
    return [o for a in parser._actions for o in a.option_strings if o.startswith("--") and o != "--help"] or ["--help"]


@pytest.mark.parametrize("argv", [[c] for c in COMMANDS if c != "bench"] + [["bench", b] for b in BENCHMARKS])
def test_a_mistyped_option_is_named_with_a_suggestion_in_every_command(argv, capsys):
    """Named before anything else is said: without the positionals and required options a command
    needs, argparse would only say what is missing ("one of the arguments --ratio --keep is
    required"), and a sub-command's option would be judged by its parent's parser (`harness bench`)."""
    options = _long_options(argv)
    typo = options[0] + "x"
    err = _usage_error(capsys, *argv, typo, "1")
    assert err.startswith(f"usage: harness {' '.join(argv)} "), err
    assert f"unrecognized arguments: {typo}" in err and f"did you mean '{options[0]}'" in err, err


def test_prune_names_the_misspelt_ratio_not_the_missing_one(capsys):
    err = _usage_error(capsys, "prune", "luigi", "o.ply", "--ration", "0.5")
    assert "unrecognized arguments: --ration" in err and "did you mean '--ratio'" in err
    assert "is required" not in err
    err = _usage_error(capsys, "prune", "luigi", "o.ply")  # nothing misspelt: what is missing
    assert "one of the arguments --ratio --keep is required" in err
    assert _usage_error(capsys, "prune", "luigi", "o.ply", "--keep=0.5", "--seed", "-1", "--x").count("--x") >= 1
