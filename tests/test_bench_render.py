"""`harness bench render` argument checking (the timing itself is a benchmark, not a test)."""

from __future__ import annotations

import argparse

import pytest

from harness.benchmarks import render
from harness.core.errors import InputError


def _args(**kw):
    p = argparse.ArgumentParser()
    render.add_arguments(p)
    ns = p.parse_args([])
    for k, v in kw.items():
        setattr(ns, k, v)
    return ns


def test_defaults():
    ns = _args()
    assert ns.scene == "bonsai-7k" and ns.views == 3 and ns.backends == "gl,reference"


@pytest.mark.parametrize("kw,source", [({"backends": "vulkan"}, "--backends"), ({"backends": ""}, "--backends"),
                                       ({"views": 0}, "--views")])
def test_bad_arguments_are_input_errors(kw, source):
    with pytest.raises(InputError) as err:
        render.run(_args(**kw))
    assert source in str(err.value)


def test_missing_scene_is_an_input_error(tmp_path):
    with pytest.raises(InputError):
        render.run(_args(scene=str(tmp_path / "nope.ply")))
