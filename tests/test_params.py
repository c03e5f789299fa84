"""Typed parameter text (vibrospeed.config): values read against the Config field types, lists
with commas, one-line errors; round trips value -> text -> value with hypothesis."""

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from vibrospeed.config import (
    config_from_params,
    format_value,
    parse_params,
    parse_value,
    type_name,
)
from vibrospeed.errors import ParameterError


@dataclasses.dataclass(frozen=True)
class Knobs:
    a: float = 1.0
    n: int = 3
    on: bool = False
    name: str = "x"
    maybe: float | None = None
    rates: tuple[float, ...] = (0.1,)
    axes: tuple[str, ...] = ()
    pair: tuple[float, float] = (0.0, 1.0)
    counts: list[int] = dataclasses.field(default_factory=list)


finite = st.floats(allow_nan=False, allow_infinity=False)
# text items that survive a comma-separated list: no comma, no surrounding blanks
word = st.text(st.characters(blacklist_characters=",", blacklist_categories=("Cs", "Z", "Cc")),
               min_size=1, max_size=12)


@given(finite)
def test_float_round_trip(x):
    assert parse_value(format_value(x), float, "a") == x


@given(st.integers(-10**12, 10**12))
def test_int_round_trip(n):
    assert parse_value(format_value(n), int, "n") == n


@given(st.booleans())
def test_bool_round_trip(b):
    assert parse_value(format_value(b), bool, "on") is b


@given(st.lists(finite, max_size=6).map(tuple))
def test_float_tuple_round_trip(xs):
    assert parse_value(format_value(xs), tuple[float, ...], "rates") == xs


@given(st.lists(word, min_size=1, max_size=5).map(tuple))
def test_str_tuple_round_trip(xs):
    assert parse_value(format_value(xs), tuple[str, ...], "axes") == xs


@given(st.one_of(st.none(), finite))
def test_optional_round_trip(x):
    assert parse_value(format_value(x), float | None, "maybe") == x


@given(st.builds(Knobs, a=finite, n=st.integers(-1000, 1000), on=st.booleans(), name=word,
                 maybe=st.one_of(st.none(), finite),
                 rates=st.lists(finite, max_size=4).map(tuple),
                 axes=st.lists(word, max_size=3).map(tuple),
                 pair=st.tuples(finite, finite),
                 counts=st.lists(st.integers(0, 99), max_size=4)))
def test_config_round_trip_through_command_line_text(k):
    """A Config written as ``-p NAME=VALUE`` flags, as a user types them, comes back equal."""
    flags = [f"{f.name}={format_value(getattr(k, f.name))}" for f in dataclasses.fields(k)]
    assert config_from_params(Knobs, parse_params(flags)) == k
    # the same flags joined by commas into one -p (a comma starts a parameter before NAME=)
    if all("=" not in format_value(getattr(k, f.name)) for f in dataclasses.fields(k)):
        assert config_from_params(Knobs, parse_params([",".join(flags)])) == k


def test_commas_belong_to_the_value_unless_a_name_follows():
    assert parse_params(["fit=q_omega,r", "comb_rates=-0.1,0.1", "q_omega=2,omega_max=100",
                         "vibration.harmonic_amps=0.1,0.05"]) == {
        "fit": "q_omega,r", "comb_rates": "-0.1,0.1", "q_omega": "2", "omega_max": "100",
        "vibration.harmonic_amps": "0.1,0.05"}
    assert parse_params(["a=1", "a=2"]) == {"a": "2"}  # the last one wins
    with pytest.raises(ParameterError, match="'q_omega' must be written NAME=VALUE"):
        parse_params(["q_omega"])


def test_values_read_as_the_field_type():
    c = config_from_params(Knobs, {"a": "1e-3", "n": "2.0", "on": "yes", "name": "a,b",
                                   "maybe": "none", "rates": "-0.3:0:0.3", "axes": "x,z",
                                   "pair": "2,3", "counts": ""})
    assert c == Knobs(a=1e-3, n=2, on=True, name="a,b", maybe=None, rates=(-0.3, 0.0, 0.3),
                      axes=("x", "z"), pair=(2.0, 3.0), counts=[])
    assert math.isinf(parse_value("inf", float))
    assert parse_value("4", float | None) == 4.0
    # values that are not text pass through unchanged
    assert config_from_params(Knobs, {"rates": (1.0, 2.0)}).rates == (1.0, 2.0)


@pytest.mark.parametrize(("params", "message"), [
    ({"a": "fast"}, "parameter 'a': cannot read 'fast' as float (a number)"),
    ({"n": "2.5"}, "parameter 'n': cannot read '2.5' as int (a whole number)"),
    ({"on": "maybe"}, "parameter 'on': cannot read 'maybe' as bool (true or false)"),
    ({"pair": "1,2,3"}, "parameter 'pair': cannot read '1,2,3' as tuple[float, float] "
                        "(2 comma-separated items, got 3)"),
    ({"rates": "0.1,x"}, "parameter 'rates[1]': cannot read 'x' as float"),
    ({"maybe": "abc"}, "parameter 'maybe': cannot read 'abc' as float | None (a number, or "
                       "none)"),
    ({"rtaes": "1"}, "unknown parameter 'rtaes' for Knobs (did you mean 'rates'"),
    ({"zzz": "1"}, "unknown parameter 'zzz' for Knobs (valid: a, axes, counts, maybe, n, "),
])
def test_errors_are_one_line_and_name_the_parameter(params, message):
    with pytest.raises(ParameterError) as info:
        config_from_params(Knobs, params)
    text = str(info.value)
    assert text.startswith(message) and "\n" not in text


def test_type_names():
    assert type_name(tuple[float, ...]) == "tuple[float, ...]"
    assert type_name(float | None) == "float | None"
    assert type_name(tuple[float, float]) == "tuple[float, float]"
    assert type_name(list[int]) == "list[int]"


def test_estimator_and_scenario_lists(tmp_path):
    """The issue's three examples reach their Configs as lists."""
    from vibrospeed import sim
    from vibrospeed.estimators import get

    grid = get("grid")
    rec = sim.simulate("cart", seed=1, duration=8,
                       **parse_params(["vibration.harmonic_amps=0.1,0.05"]))
    assert rec.meta["config"]["vibration"]["harmonic_amps"] == (0.1, 0.05)
    cfg = grid.config_for(rec, params=parse_params(["comb_rates=-0.1,0.1", "fit=q_omega,r",
                                                    "smooth=none"]))
    assert cfg.comb_rates == (-0.1, 0.1)
    assert cfg.tracker.fit == "q_omega,r"


def test_scenario_knob_errors_name_the_dotted_knob():
    from vibrospeed import sim

    with pytest.raises(ParameterError, match=r"^parameter 'vibration.harmonic_amps\[1\]': "
                       r"cannot read 'b' as float"):
        sim.simulate("cart", duration=5, **parse_params(["vibration.harmonic_amps=0.1,b"]))
    with pytest.raises(ParameterError, match=r"unknown parameter 'vibraton.harmonic_amps' for "
                       r"CartConfig \(did you mean 'vibration'"):
        sim.simulate("cart", duration=5, **parse_params(["vibraton.harmonic_amps=1"]))


@pytest.mark.parametrize("method,name", [("ekf", "comb"), ("aided", "causal"),
                                         ("fuse", "online"), ("rbpmf", "improved"),
                                         ("grid", "improved")])
def test_an_estimator_switch_outside_the_configs_is_read_strictly(method, name):
    """A switch that is not a Config field (read by the method's estimate) takes true/false,
    1/0, yes/no, on/off; other text is a one-line ParameterError naming it."""
    from vibrospeed import estimators, sim
    from vibrospeed.config import parse_flag
    from vibrospeed.errors import ParameterError

    assert parse_flag("Yes", name) is True and parse_flag("off", name) is False
    assert parse_flag(0, name) is False and parse_flag(True, name) is True
    rec = sim.simulate("car", seed=1, duration=4.0)
    with pytest.raises(ParameterError, match=f"'{name}'.*'perhaps'"):
        estimators.get(method).estimate(rec, wheel_radius=0.3, params={name: "perhaps"})


def test_grid_reads_improved_and_is_the_improved_filter_either_way():
    """``-m grid`` is the improved RBPMF: ``improved`` (read as a switch, as ``rbpmf`` reads
    it) leaves its numbers as they are without it, bit for bit."""
    from vibrospeed import sim
    from vibrospeed.estimators import grid

    rec = sim.simulate("car", seed=1, duration=4.0)
    base = grid.estimate(rec, wheel_radius=0.3).omega
    for value in ("true", "false", "yes", 0):
        tr = grid.estimate(rec, wheel_radius=0.3, params={"improved": value})
        assert np.array_equal(tr.omega, base, equal_nan=True)


def test_a_number_read_outside_the_configs():
    """``config.parse_number`` reads a number an estimator takes itself as a ``float``
    (``float | None``) field reads it: numbers and their text alike, ``none`` / empty only
    where optional, other text one line naming the parameter."""
    from vibrospeed.config import parse_number

    assert [parse_number(v, "x") for v in ("5", " 1e-3 ", "-inf", 2, 0.5)] == \
        [5.0, 1e-3, -math.inf, 2.0, 0.5]
    assert type(parse_number(2, "x")) is float
    assert [parse_number(v, "x", optional=True) for v in ("none", "", None, "4")] == \
        [None, None, None, 4.0]
    with pytest.raises(ParameterError, match=r"^parameter 'x': cannot read 'none' as float"):
        parse_number("none", "x")
    with pytest.raises(ParameterError, match=r"^parameter 'lp_cutoff': cannot read 'abc' as "
                                             r"float \| None \(a number, or none\)$"):
        parse_number("abc", "lp_cutoff", optional=True)


def test_text_that_cannot_be_read_is_quoted_on_one_line():
    """The refused text as Python writes it: a newline or a quote in it stays on the one line."""
    for text in ("4\n5", "it's", "tab\there"):
        with pytest.raises(ParameterError) as exc:
            parse_value(text, float, "omega_max")
        assert "\n" not in str(exc.value)
        assert str(exc.value) == f"parameter 'omega_max': cannot read {text!r} as float (a number)"
