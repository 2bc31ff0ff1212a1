"""Numbers in exponent form read as numbers, in config files and on the command line
(YAML 1.1 would read ``1e6`` as a string, and a number field would refuse it)."""

from __future__ import annotations

import pytest

from baselines.scenario_spec import parse_set
from scenario_gen.schema import parse_yaml


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("1e6", 1e6),
        ("-2e-3", -2e-3),
        ("+3E+2", 300.0),
        ("1_000e1", 1e4),
        ("1.5e3", 1500.0),
        (".5e1", 5.0),
    ],
)
def test_exponent_floats_are_numbers(text: str, value: float) -> None:
    got = parse_yaml(f"x: {text}", "test")["x"]
    assert isinstance(got, float) and got == value


@pytest.mark.parametrize("text", ['"1e6"', "1e6x", "e6", "1e", "0x1e"])
def test_what_is_not_an_exponent_float_stays_what_it_was(text: str) -> None:
    assert not isinstance(parse_yaml(f"x: {text}", "test")["x"], float)


def test_a_command_line_value_in_exponent_form_reaches_the_env_config() -> None:
    import gymnasium as gym

    import agrinav_gym  # noqa: F401

    over = parse_set(["gnss.fix.multipath_mtbf_s=1e6"], "--config")
    assert over == {"gnss.fix.multipath_mtbf_s": 1e6}
    env = gym.make("AgriNav/FurrowFollow-v3", config={"gnss": {"fix": {"multipath_mtbf_s": 1e6}}})
    try:
        assert env.unwrapped.cfg.gnss.fix.multipath_mtbf_s == 1e6
    finally:
        env.close()


@pytest.mark.parametrize("text", ["36:32:57", "1:30", "-5:30", "1:30.5"])
def test_base_60_is_a_string_as_in_yaml_1_2(text: str) -> None:
    # YAML 1.1 read 36:32:57 as 131577: degrees:minutes:seconds taken as a wrong number
    assert parse_yaml(f"x: {text}", "test")["x"] == text


@pytest.mark.parametrize(
    ("text", "value"),
    [("12", 12), ("-3", -3), ("0x1F", 31), ("012", 10), ("1_000", 1000), ("-3.5", -3.5)],
)
def test_base_10_numbers_read_as_before(text: str, value: float) -> None:
    got = parse_yaml(f"x: {text}", "test")["x"]
    assert got == value and type(got) is type(value)


def test_infinities_and_nan_read_as_before() -> None:
    got = parse_yaml("a: .inf\nb: -.Inf\nc: .nan", "test")
    assert got["a"] == float("inf") and got["b"] == float("-inf") and got["c"] != got["c"]
