"""Names → file names (harness.core.names): one to one, bounded, never a path; the checks of a
config's names before any work; labels drawn as text; messages that never drive the terminal."""

from __future__ import annotations

import re

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from harness.core.errors import InputError, printable
from harness.core.names import NAME_MAX, collisions, file_name, name_problem
from harness.run.config import parse_config

names = st.text(min_size=0, max_size=90)


@settings(max_examples=400, deadline=None)
@given(a=names, b=names)
def test_distinct_names_get_distinct_file_names(a, b):
    assert (file_name(a) == file_name(b)) == (a == b)


@settings(max_examples=400, deadline=None)
@given(name=names)
def test_a_file_name_is_one_bounded_plain_component(name):
    f = file_name(name)
    assert re.fullmatch(r"[A-Za-z0-9_.~-]+", f) and f not in (".", "..") and not f.startswith(".")
    assert len(f) <= 64 and "__" not in f  # the separator of render file names stays unambiguous
    assert file_name(name) == f  # the same every time


@pytest.mark.parametrize("name, expected", [("bonsai-7k", "bonsai-7k"), ("x_y", "x_y"), ("opacity", "opacity"),
                                            ("k=0.1,voxel=0.2", None), ("x/y", None), ("..", None), ("a__b", None)])
def test_plain_names_are_themselves(name, expected):
    assert (file_name(name) == name) == (expected is not None)


def test_the_issues_collisions_are_gone():
    assert len({file_name(n) for n in ("x/y", "x_y", "x y", "x:y")}) == 4
    assert file_name("a b") != file_name("a_b")
    assert len(file_name("n" * 300)) < 64 and file_name("..") not in (".", "..")


def test_case_is_what_collisions_refuse():
    assert collisions([("scenes[0]", "A"), ("scenes[1]", "a")]) == ("scenes[0]", "scenes[1]")
    assert collisions([("scenes[0]", "x/y"), ("scenes[1]", "x_y"), ("scenes[2]", "a")]) is None


@pytest.mark.parametrize("name, phrase", [("red\x1b[31m", "control character U+001B"), ("a\u202eb", "U+202E"),
                                          ("line\nbreak", "U+000A"), ("n" * (NAME_MAX + 1), "characters long")])
def test_name_problems(name, phrase):
    assert phrase in name_problem(name)


def _config(tmp_path, scenes, methods=("opacity",)):
    return {"name": "t", "output": str(tmp_path / "out"), "ratios": [0.3], "scenes": scenes, "methods": list(methods)}


@pytest.mark.parametrize("scenes, methods, phrase", [
    ([{"name": "A", "source": "s.ply"}, {"name": "a", "source": "s.ply"}], ["opacity"], "differ only in case"),
    ([{"name": "n" * 300, "source": "s.ply"}], ["opacity"], "scenes[0].name: is 300 characters long"),
    ([{"name": "s", "source": "s.ply", "label": "\x1b[2J"}], ["opacity"], "scenes[0].label: '\\x1b[2J' holds"),
    ([{"name": "s", "source": "s.ply"}], [{"name": "opacity", "variant": "V"}, {"name": "opacity", "variant": "v"}],
     "opacity variant 'V' and opacity variant 'v' differ only in case"),
])
def test_a_configs_names_are_checked_when_it_is_read(tmp_path, scenes, methods, phrase):
    with pytest.raises(InputError) as info:
        parse_config(_config(tmp_path, scenes, methods), "c.yaml")
    assert phrase in str(info.value) and "\x1b" not in str(info.value)


def test_names_that_only_looked_alike_are_accepted(tmp_path):
    cfg = parse_config(_config(tmp_path, [{"name": "x/y", "source": "s.ply"}, {"name": "x_y", "source": "s.ply"},
                                          {"name": "..", "source": "s.ply", "label": "$\\x$"}]), "c.yaml")
    assert [s.name for s in cfg.scenes] == ["x/y", "x_y", ".."]


def test_messages_escape_what_a_terminal_would_act_on():
    err = InputError("sc\x1bene", "bad \x00 name \u202e")
    assert str(err) == "sc\\x1bene: bad \\x00 name \\u202e" and printable("plain é") == "plain é"


def test_a_tex_label_is_drawn_as_text(tmp_path):
    """A plot label ``$\\x$`` killed the run at its plots: labels are text, never mathtext."""
    import pandas as pd

    from harness.report.plots import write_plots
    from harness.report.results import to_frame
    from tests.stress.cases import _run_dir

    run = _run_dir(tmp_path)
    df = pd.read_parquet(run / "results.parquet").assign(label="$\\x$", scene="$\\x$")
    written = write_plots(to_frame(df.to_dict("records")), run, ["curves"])
    assert written.paths and all(p.stat().st_size > 1000 for p in written.paths), written.missing
