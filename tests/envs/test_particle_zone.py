"""The particle pile's digging zone as an option (``soil_options={"zone_scale": ...}``):
a larger zone puts its walls and static core further from the bucket, with more grains of
the same size and the same bulk mass each."""

from __future__ import annotations

import gymnasium as gym
import pytest

import pilerl  # noqa: F401

COARSE = {"mouth_grains": 4.0}  # fast to build


def _soil(**options):
    env = gym.make("pilerl/PileLoading-v0", soil="particles", soil_options={**COARSE, **options})
    return env.unwrapped.soil


def test_a_larger_zone_holds_more_grains_of_the_same_size_further_out():
    default, larger = _soil(), _soil(zone_scale=1.3)
    assert larger.radius_m == default.radius_m  # the resolution stays
    assert larger.x_back_m > default.x_back_m + 0.3  # the back wall: 1.3 m -> 1.7 m
    assert larger.half_width_m > default.half_width_m + 0.15  # the side walls: 0.75 -> 0.98 m
    assert larger.active_depth_m == pytest.approx(1.3 * default.active_depth_m)
    # volume grows by about 1.3^2 in plan and deeper still: at least twice the grains
    assert larger.n_particles > 2 * default.n_particles
    # each grain carries the bulk mass of its share of the zone, whatever the zone
    assert larger.particle_mass_kg == pytest.approx(default.particle_mass_kg, rel=0.1)


@pytest.mark.parametrize("bad", [0.4, 2.5, float("nan"), True, "1.3"])
def test_impossible_zone_scale_fails_naming_the_option(bad):
    with pytest.raises(ValueError, match="zone_scale"):
        gym.make("pilerl/PileLoading-v0", soil="particles", soil_options={"zone_scale": bad})
