"""Condition presets and their validation."""

from __future__ import annotations

import argparse

import pytest
from pilerl_pile_loader.conditions import (
    CONDITIONS,
    get_condition,
    overrides_argument,
    parse_overrides,
)


def test_paper_conditions_exist():
    assert set(CONDITIONS) == {"summer", "winter_a", "winter_b", "winter_c", "winter_d"}


def test_winter_is_more_slippery_and_has_colder_oil_than_summer():
    summer = get_condition("summer")
    for name in ("winter_b", "winter_c"):
        winter = get_condition(name)
        assert winter.ground.tyre_friction < summer.ground.tyre_friction / 2
        assert winter.hydraulics.valve_lag_s > summer.hydraulics.valve_lag_s


def test_unknown_condition_lists_known_ones():
    with pytest.raises(ValueError, match=r"unknown condition 'autumn'.*summer"):
        get_condition("autumn")


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"material": {"density_kg_m3": -5.0}}, "density_kg_m3"),
        ({"material": {"cohesion_pa": float("nan")}}, "cohesion_pa"),
        ({"ground": {"tyre_friction": 0.0}}, "tyre_friction"),
        ({"hydraulics": {"valve_lag_s": 0.0}}, "valve_lag_s"),
        ({"material": {"colour": 1}}, r"unknown field\(s\) \['colour'\]"),
        ({"weather": {}}, "unknown section 'weather'"),
    ],
)
def test_impossible_overrides_fail_naming_the_field(overrides, message):
    with pytest.raises(ValueError, match=message):
        get_condition("summer").with_overrides(overrides)


def test_valid_override_changes_only_that_field():
    base = get_condition("summer")
    changed = base.with_overrides({"material": {"density_kg_m3": 1500.0}})
    assert changed.material.density_kg_m3 == 1500.0
    assert changed.material.friction_angle_deg == base.material.friction_angle_deg
    assert changed.ground == base.ground


def test_overrides_from_a_command_line_are_parsed():
    assert parse_overrides('{"material": {"cohesion_pa": 0}}') == {"material": {"cohesion_pa": 0}}


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("nope", "not JSON"),
        ('{"material": 5}', "expected an object"),
        ('["material"]', "expected an object"),
        ('{"material": {"cohesion_pa": "x"}}', r"material\.cohesion_pa: not a number"),
        ('{"material": {"cohesion_pa": true}}', r"material\.cohesion_pa: not a number"),
        ('{"materal": {}}', "unknown section 'materal'"),
        ('{"ground": {"tyre_frictio": 1}}', "tyre_frictio"),
        ('{"material": {"cohesion_pa": -1}}', "cohesion_pa: must be >= 0"),
    ],
)
def test_bad_overrides_from_a_command_line_fail_naming_the_problem(text, message):
    with pytest.raises(ValueError, match=message):
        parse_overrides(text)


def test_a_command_line_s_bad_overrides_are_a_parser_error_naming_the_field():
    parser = argparse.ArgumentParser()
    parser.add_argument("--overrides", type=overrides_argument)
    assert parser.parse_args(["--overrides", '{"ground": {"tyre_friction": 0.3}}']).overrides == {
        "ground": {"tyre_friction": 0.3}
    }
    with pytest.raises(argparse.ArgumentTypeError, match="tyre_frictio"):
        overrides_argument('{"ground": {"tyre_frictio": 0.3}}')
