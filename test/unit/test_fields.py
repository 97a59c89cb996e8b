"""Typed, range-checked fields: the one mechanism behind SlamConfig, SimConfig and NodeConfig."""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import pytest

from fastslam.fields import ConfigError, check_fields, choice, coerce, num


@dataclass(frozen=True)
class Demo:
    count: int = num(3, 1, 10, "a count")
    gain: float = num(0.5, 0.0, 1.0, "a gain")
    mode: str = choice("a", ("a", "b"), "a mode")
    flag: bool = False
    limit: float | None = None
    names: list = dataclasses.field(default_factory=list)


def test_metadata_of_num_and_choice():
    f = {x.name: x for x in dataclasses.fields(Demo)}
    assert f["count"].default == 3 and f["count"].metadata["range"] == (1, 10)
    assert f["count"].metadata["doc"] == "a count"
    assert f["mode"].metadata["choices"] == ("a", "b")


def test_coerce_converts_what_is_meant():
    assert coerce(Demo, {"count": 4.0, "gain": 1, "flag": 1, "mode": "b", "limit": None, "names": ["x"]}) == \
        {"count": 4, "gain": 1.0, "flag": True, "mode": "b", "limit": None, "names": ["x"]}
    out = coerce(Demo, {"count": 7.0, "limit": 2})
    assert out == {"count": 7, "limit": 2.0} and type(out["count"]) is int and type(out["limit"]) is float


@pytest.mark.parametrize("values, message", [
    ({"count": 2.5}, "count=2.5 must be an integer"),
    ({"count": True}, "count=True must be an integer, not true/false"),
    ({"count": "3"}, "count='3' must be an integer"),
    ({"gain": True}, "gain=True must be a number"),
    ({"flag": "yes"}, "flag='yes' must be true or false"),
    ({"flag": 2}, "flag=2 must be true or false"),
    ({"mode": 3}, "mode=3 must be a string"),
    ({"names": "x"}, "names='x' must be a list"),
    ({"cnt": 1}, "unknown parameter 'cnt' (known: count, flag, gain, limit, mode, names)"),
])
def test_coerce_rejects_wrong_types_naming_the_key(values, message):
    with pytest.raises(ConfigError) as err:
        coerce(Demo, values)
    assert str(err.value) == message


@pytest.mark.parametrize("demo, message", [
    (Demo(count=11), "count=11 must be in [1, 10]"),
    (Demo(count=0), "count=0 must be in [1, 10]"),
    (Demo(gain=math.inf), "gain=inf must be in [0.0, 1.0]"),
    (Demo(gain=True), "gain=True must be in [0.0, 1.0]"),     # a bool is not a number here
    (Demo(mode="c"), "mode='c' must be one of a, b"),
])
def test_check_fields_names_the_first_bad_field(demo, message):
    with pytest.raises(ConfigError) as err:
        check_fields(demo)
    assert str(err.value) == message


def test_check_fields_accepts_the_bounds_and_none():
    check_fields(Demo(count=1, gain=1.0, limit=None))
    check_fields(Demo(count=10, gain=0.0, mode="b"))
    assert issubclass(ConfigError, ValueError)


@dataclass(frozen=True)
class Switch:
    on: int = num(1, 0, 1, "a 0/1 switch")


def test_a_zero_one_switch_takes_true_and_false():
    assert coerce(Switch, {"on": False}) == {"on": 0} and coerce(Switch, {"on": True}) == {"on": 1}
