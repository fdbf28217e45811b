"""Typed parameters (harness.core.params) and the ratio vocabulary (harness.core.ratios)."""

from __future__ import annotations

import math
from dataclasses import FrozenInstanceError, dataclass
from typing import Literal

import pytest
from hypothesis import given
from hypothesis import strategies as st

from harness.core import ratios
from harness.core.params import ParamError, Params, param


@dataclass(frozen=True)
class P(Params):
    size: float = param(0.5, gt=0, le=1, doc="a fraction")
    count: int = param(3, ge=1, doc="a count")
    flag: bool = param(False, doc="a switch")
    mode: Literal["a", "b"] = param("a", doc="a choice")
    cap: int | None = param(None, ge=0, doc="optional")


def test_defaults_specs_and_description():
    p = P.parse()
    assert p == P() and p.to_dict() == {"size": 0.5, "count": 3, "flag": False, "mode": "a", "cap": None}
    specs = {s.name: s for s in P.specs()}
    assert specs["size"].describe() == "float > 0, <= 1"
    assert specs["mode"].describe() == "one of a, b"
    assert specs["cap"].describe() == "int >= 0 or none"
    with pytest.raises(FrozenInstanceError):
        p.size = 0.1


@pytest.mark.parametrize("values, message", [
    ({"size": 0}, "size: 0.0 is not > 0"), ({"size": 1.5}, "size: 1.5 is not <= 1"),
    ({"size": float("nan")}, "size: expected a finite number"), ({"size": float("inf")}, "expected a finite"),
    ({"size": "0.1"}, "size: expected a number, got '0.1'"), ({"size": True}, "size: expected a number"),
    ({"count": 2.0}, "count: expected an integer"), ({"count": True}, "count: expected an integer"),
    ({"count": 0}, "count: 0 is not >= 1"), ({"flag": 1}, "flag: expected true or false"),
    ({"mode": "c"}, "mode: 'c' is not one of a, b"), ({"count": None}, "count: must not be null"),
    ({"nope": 1}, "nope: no such parameter; known: size, count, flag, mode, cap"),
])
def test_every_bad_value_names_the_key(values, message):
    with pytest.raises(ParamError) as info:
        P.parse(values)
    assert message in str(info.value) and info.value.key == next(iter(values))


def test_text_values_from_the_command_line():
    p = P.parse_text({"size": "0.25", "count": "7", "flag": "yes", "mode": "b", "cap": "none"})
    assert p == P(size=0.25, count=7, flag=True, mode="b", cap=None)
    assert P.parse_text({"size": "1"}).size == 1.0 and P.parse_text({"flag": "0"}).flag is False
    for values, message in (({"count": "2.5"}, "count: expected int >= 1, got '2.5'"),
                            ({"flag": "maybe"}, "flag: expected bool"), ({"size": "inf"}, "finite")):
        with pytest.raises(ParamError, match=message):
            P.parse_text(values)


@given(st.floats(allow_nan=True, allow_infinity=True), st.integers(-5, 5))
def test_parse_accepts_exactly_the_declared_domain(size, count):
    ok = math.isfinite(size) and 0 < size <= 1 and count >= 1
    try:
        p = P.parse({"size": size, "count": count})
    except ParamError:
        assert not ok
    else:
        assert ok and p.size == size and p.count == count


@given(st.floats(0, 1))
def test_ratio_and_keep_are_one_vocabulary(r):
    c = ratios.canonical(r)
    assert ratios.same(ratios.from_keep(ratios.to_keep(c)), c)
    assert ratios.merge([c], [ratios.to_keep(c)]) == (c,)


def test_ratios_canonical_merge_and_errors():
    assert ratios.from_keep(0.7) == 0.3 and ratios.merge([0.3, 0.1], [0.7, 0.5]) == (0.1, 0.3, 0.5)
    assert ratios.percent(0.3) == "30%" and ratios.same(0.3, 0.1 + 0.2) and not ratios.same(0.3, 0.3001)
    for bad in (-0.1, 1.5, float("nan"), float("inf")):
        with pytest.raises(ValueError):
            ratios.canonical(bad)


def test_a_tuple_of_numbers_is_a_parameter_too():
    from dataclasses import dataclass

    from harness.core.params import ParamError, Params, param

    @dataclass(frozen=True)
    class Rings(Params):
        above: tuple[float, ...] = param((15.0, 30.0), ge=-80, le=80, doc="degrees above")

    spec = Rings.specs()[0]
    assert spec.many and spec.describe() == "list of float >= -80, <= 80"
    assert Rings.parse({"above": [40, 50.5]}).above == (40.0, 50.5) and Rings.parse({}).above == (15.0, 30.0)
    assert Rings.parse_text({"above": "10, 20"}).above == (10.0, 20.0)
    with pytest.raises(ParamError, match="above: 90.0 is not <= 80"):
        Rings.parse({"above": [10, 90]})
    with pytest.raises(ParamError, match="above: expected a list of float values"):
        Rings.parse({"above": 10})
