"""circsim.config.validate: each check turns YAML-like data into a typed value or raises one line naming
the key path and what was expected; numbers accept exactly their bounds; sections refuse unknown and
missing keys at their path; a merger rule's refusal keeps the rule's words after the key."""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from circsim.config.validate import (
    Invalid,
    boolean,
    choice,
    describe,
    integer,
    number,
    optional,
    optional_path,
    refused,
    ruled,
    section,
    seq,
    string,
    vec2,
)


@settings(max_examples=200, deadline=None)
@given(v=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10, 10)),
       lo=st.sampled_from([None, -1.0, 0.0, 2.5]), hi=st.sampled_from([None, 0.0, 3.0, 10.0]),
       open_lo=st.booleans(), open_hi=st.booleans())
def test_a_number_is_accepted_exactly_within_its_bounds(v, lo, hi, open_lo, open_hi):
    kw = {}
    if lo is not None:
        kw["gt" if open_lo else "ge"] = lo
    if hi is not None:
        kw["lt" if open_hi else "le"] = hi
    check = number(**kw)
    ok = math.isfinite(v) and (lo is None or (v > lo if open_lo else v >= lo)) and \
        (hi is None or (v < hi if open_hi else v <= hi))
    if ok:
        out = check(v, "a.b")
        assert out == v and type(out) is float
    else:
        with pytest.raises(Invalid) as e:
            check(v, "a.b")
        assert e.value.path == "a.b" and e.value.text == f"a.b: expected {check.expected}, got {v!r}"


def test_the_words_of_the_bounds():
    assert number(gt=0).expected == "a number > 0"
    assert number(ge=0, le=1).expected == "a number in [0, 1]"
    assert number(gt=0, lt=1.5).expected == "a number in (0, 1.5)"
    assert number(le=3).expected == "a number <= 3" and number().expected == "a number"
    assert integer(ge=1).expected == "an integer >= 1" and integer(ge=0, le=9).expected == "an integer in [0, 9]"
    assert describe(number(gt=0, why="the datasheet")) == "a number > 0 — the datasheet"


@pytest.mark.parametrize("check, good, bads", [
    (number(), 2, [True, "2", None, [2]]),  # a bool is not a number
    (integer(ge=0, le=5), 3, [True, 2.0, -1, 6, "3"]),
    (boolean, False, [0, 1, "true", None]),
    (string, "x", [1, None, ["x"]]),
    (choice("a", "b"), "b", ["c", ["a"], {"a": 1}, None]),
    (optional_path, None, [3, ["p"]]),
    (optional(integer(ge=1)), None, [0, "x"]),
])
def test_checks_accept_and_refuse(check, good, bads):
    assert check(good, "k") == good
    for v in bads:
        with pytest.raises(Invalid) as e:
            check(v, "k")
        assert e.value.text.startswith("k: expected ") and e.value.text.endswith(f", got {v!r}")


def test_sequences_name_the_failing_item():
    check = seq(integer(ge=0), "a list of counts", min_len=1)
    assert check([1, 2], "xs") == (1, 2)
    with pytest.raises(Invalid, match=r"^xs\[2\]: expected an integer >= 0, got -4$"):
        check([1, 2, -4], "xs")
    with pytest.raises(Invalid, match=r"^xs: expected a list of counts, got \[\]$"):
        check([], "xs")
    xy = vec2(ge=0)
    assert xy([1, 2.5], "p") == (1.0, 2.5)
    with pytest.raises(Invalid, match=r"^p: expected a list \[x, y\] of two numbers >= 0, got \[1, 2, 3\]$"):
        xy([1, 2, 3], "p")
    with pytest.raises(Invalid, match=r"^p\[1\]: expected a number >= 0, got -1$"):
        xy([1, -1], "p")


@dataclass(frozen=True)
class Thing:
    size: float = 1.0
    name: str = "t"


def test_a_section_checks_key_by_key_and_refuses_unknown_or_missing_keys():
    check = section(Thing, {"size": number(gt=0), "name": string, "type": choice("thing")}, required=("name",))
    assert check({"name": "a", "type": "thing"}, "world.objects[2]") == Thing(1.0, "a")  # type: checked, not passed
    assert check({"name": "b", "size": 2}, "x") == Thing(2.0, "b")
    with pytest.raises(Invalid, match=r"^world.objects\[2\].colour: unknown key; expected one of size, name, type$"):
        check({"name": "a", "colour": "red"}, "world.objects[2]")
    with pytest.raises(Invalid, match=r"^x.name: missing required key$"):
        check({"size": 1}, "x")
    with pytest.raises(Invalid, match=r"^x.size: expected a number > 0, got 0$"):
        check({"name": "a", "size": 0}, "x")
    with pytest.raises(Invalid, match=r"^x: expected a mapping with keys size, name, type, got \[1\]$"):
        check([1], "x")
    assert section(Thing, {"size": number()})(None, "top") == Thing()  # null: the defaults
    assert section(Thing, {"size": number()})({"size": 3}, "")  # the top level: keys without a prefix
    with pytest.raises(Invalid, match=r"^bogus: unknown key"):
        section(Thing, {"size": number()})({"bogus": 1}, "")


def test_a_merger_rules_refusal_keeps_its_words_after_the_key():
    class SettingError(ValueError):
        def __init__(self, key, rest):
            super().__init__(f"{key}{rest}")
            self.rest = rest

    def rule(v, key):
        if v < 0:
            raise SettingError(key, " must be at least 0 (metres)")
        return v

    rule.expected, rule.why = "at least 0", "a distance"
    check = ruled(rule)
    assert check(2, "merger.window_m") == 2
    with pytest.raises(Invalid) as e:
        check(-1, "merger.window_m")
    assert e.value.text == "merger.window_m must be at least 0 (metres)"
    assert describe(check) == "at least 0 — a distance"
    plain = refused(ValueError("boom"), "a.b")
    assert plain.text == "a.b: boom" and plain.message == "boom"
