"""The heightfield against the particle pile on the same material (docs/soil_models.md,
"Comparing the two soils on the same material").

On a loose material (summer's dry gravel, no cohesion on either soil) the heightfield's
mouth intake, which
admits only what the bucket mouth sweeps, fills the scripted expert's scoop as the particle
pile does (0.476 and 0.414, seeds 0-3), where the default footprint intake fills it to the
cap (1.10). On a cohesive material (winter_a's wet gravel, 4 kPa) the mouth intake fills
about half of what it fills on the same gravel without cohesion.

The summer agreement is checked on the mean of the benchmark's four seeds (0-3), at the
particle pile's default resolution: about a minute of CPU, the price of checking the two
soils against each other at all. Particle fills scatter between seeds (the default
expert: 0.36, 0.45, 0.40, 0.44 since session 33's sleep rule, mean 0.414; seed 0 alone was
0.467 before it), so one seed would test the scatter (``benchmarks/particle_resolution.py
--mouth-grains 6 --seeds 4``, ``benchmarks/same_actions.py --tables expert``).

Session 30 raised the particle pile's CG iterations from 20 to 30 (the tyres' contacts were
unresolved at 20): the summer fills above are the 20-iteration pile's; at 30 the four seeds
fill 0.29 (0.22, 0.37, 0.28, 0.28) with the expert of the time (docs/soil_models.md, "The
drive pressure's chatter on ice"). Session 31 traced that to the expert's impact cue, which
fired on the grains' impact burst; session 32's stall cue with pushing again fills the two
soils alike (0.428 against 0.476 by mass on seeds 0-3, "A stall cue that reads both soils
alike"), and session 33 made it the default expert: the first test checks the default, the
second that the earlier rise cue does not read the two soils alike. Session 33 also keeps
the grains awake while the machine touches them (docs/soil_models.md, "Speed"), which moves
single seeds (seed 0 of the default expert 0.467 to 0.363) and not the four seeds' mean."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from pilerl_pile_loader.operator import make_expert

import pilerl  # noqa: F401

SEED = 0
SEEDS = (0, 1, 2, 3)  # the summer agreement's starts: the benchmarks' four seeds
AGREEMENT = 0.15  # issue #15 item 3: within 15 % of each other
LOOSE = {"material": {"cohesion_pa": 0.0}}


def expert_fill(
    condition: str, soil: str, style: dict | None = None, seed: int = SEED, **env_kwargs
) -> float:
    """The nominal expert's final fill on one seeded start (noiseless sensors); ``style``:
    ``OperatorStyle`` fields to set."""
    env = gym.make(
        "pilerl/PileLoading-v0", condition=condition, soil=soil, sensor_noise=0.0, **env_kwargs
    )
    obs, _ = env.reset(seed=seed)
    expert = make_expert(dt=env.unwrapped.dt, **(style or {}))
    expert.reset()
    while True:
        obs, _, terminated, truncated, info = env.step(expert.act(obs))
        if terminated or truncated:
            env.close()
            return float(info["fill_fraction"])


@pytest.fixture(scope="module")
def summer_fills() -> dict[str, float]:
    """The nominal expert's mean summer fill over ``SEEDS`` on the particle pile and both
    heightfield intakes."""
    soils = {
        "particles": {"soil": "particles"},
        "mouth": {"soil": "heightfield", "soil_options": {"intake": "mouth"}},
        "footprint": {"soil": "heightfield"},
    }
    return {
        name: float(np.mean([expert_fill("summer", seed=seed, **soil) for seed in SEEDS]))
        for name, soil in soils.items()
    }


def test_on_loose_gravel_the_mouth_intake_fills_like_the_particle_pile(summer_fills):
    """The default expert lifts once the machine stops pushing and crowds again once the
    boom is free (docs/soil_models.md, "A stall cue that reads both soils alike"): 0.414
    against 0.476 in session 33, a ratio of 0.870 against the bound 0.85 (the issue's 15 %):
    near the edge, so a change that lowers the particle mean by 0.01 fails here, and should
    be judged on more seeds before the bound is questioned."""
    assert abs(summer_fills["particles"] / summer_fills["mouth"] - 1.0) <= AGREEMENT


def test_the_earlier_rise_cue_lifts_on_the_grains_impact_burst_and_underfills_them():
    """The expert before session 33 (``impact_cue="rise"``, no second push) takes the
    particle face's impact burst for the impact and lifts early: seed 0 fills the
    particles to under half the mouth intake's fill (0.223 against 0.481 when written;
    docs/soil_models.md, "Same actions on both soils")."""
    style = {"impact_cue": "rise", "push_again": False}
    particles = expert_fill("summer", "particles", style)
    mouth = expert_fill("summer", "heightfield", style, soil_options={"intake": "mouth"})
    assert particles < (1.0 - AGREEMENT) * mouth


def test_the_default_intake_fills_more_than_passes_the_mouth(summer_fills):
    assert 0.15 < summer_fills["particles"] < 0.7  # a real scoop, not an empty bucket
    # the default intake takes what the bucket's floor and back plate push aside too
    assert summer_fills["footprint"] > 1.5 * summer_fills["particles"]
    assert summer_fills["footprint"] > 1.5 * summer_fills["mouth"]


def test_cohesion_keeps_the_mouth_scoop_light():
    mouth = {"intake": "mouth"}
    cohesive = expert_fill("winter_a", "heightfield", soil_options=mouth)
    loose = expert_fill("winter_a", "heightfield", soil_options=mouth, condition_overrides=LOOSE)
    assert cohesive < 0.6 * loose
    assert loose >= 0.5  # on the same gravel without cohesion the scoop fills half a bucket
