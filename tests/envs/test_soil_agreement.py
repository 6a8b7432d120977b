"""The heightfield against the particle pile on the same material (docs/soil_models.md,
"Comparing the two soils on the same material").

On a loose material (summer's dry gravel, no cohesion on either soil) the heightfield's
mouth intake, which
admits only what the bucket mouth sweeps, fills the scripted expert's scoop as the particle
pile does (0.48 and 0.47 on seed 0), where the default footprint intake fills it to the
cap (1.10). On a cohesive material (winter_a's wet gravel, 4 kPa) the mouth intake fills
about half of what it fills on the same gravel without cohesion.

One seed, at the particle pile's default resolution: ~20 s of CPU (a whole scoop, ~0.5x
real time), the price of checking the two soils against each other at all. Particle fills
scatter between seeds (0.47, 0.57, 0.37, 0.46 on seeds 0-3, mean 0.467, the mouth intake
0.484): seed 0 lies near their mean, so a change to either soil's physics that moves this
test should be judged on the benchmark's four seeds
(``benchmarks/particle_resolution.py --mouth-grains 6 --seeds 4``), not on this one.

Session 30 raised the particle pile's CG iterations from 20 to 30 (the tyres' contacts were
unresolved at 20): the summer fills above are the 20-iteration pile's; at 30 the four seeds
fill 0.29 (0.22, 0.37, 0.28, 0.28), so the first test is an expected failure until that is
traced (docs/soil_models.md, "The drive pressure's chatter on ice"). Session 31 traced it
to the expert's impact cue; session 32's stall cue with pushing again (off by default)
fills the two soils alike, which the second test checks (docs/soil_models.md, "A stall cue
that reads both soils alike"), on seeds 0-3 since session 33 (its sleep rule moved seed 0
alone out of the band, the mean not: docs/soil_models.md, "Speed")."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from pilerl_pile_loader.operator import make_expert

import pilerl  # noqa: F401

SEED = 0
STALL_SEEDS = (0, 1, 2, 3)  # the stall cue's check: the benchmark's four seeds
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
    """The nominal expert's summer fill on the particle pile and both heightfield intakes."""
    return {
        "particles": expert_fill("summer", "particles"),
        "mouth": expert_fill("summer", "heightfield", soil_options={"intake": "mouth"}),
        "footprint": expert_fill("summer", "heightfield"),
    }


@pytest.mark.xfail(
    strict=True,
    raises=AssertionError,
    reason="session 30: measured on the 20-iteration particle pile, whose tyre contacts were "
    "unresolved; with 30 CG iterations the four seeds fill 0.29 against the mouth intake's "
    "0.48 (docs/soil_models.md, 'The drive pressure's chatter on ice'); traced in session "
    "31 to the expert's impact cue, which fires on the grains' impact burst: the same "
    "commands fill both soils alike ('Same actions on both soils')",
)
def test_on_loose_gravel_the_mouth_intake_fills_like_the_particle_pile(summer_fills):
    assert abs(summer_fills["particles"] / summer_fills["mouth"] - 1.0) <= AGREEMENT


def test_with_the_stall_cue_and_pushing_again_the_mouth_intake_fills_like_the_particles():
    """Session 32 (docs/soil_models.md, "A stall cue that reads both soils alike"): an
    expert that lifts once the machine stops pushing, and crowds again once the boom is
    free, fills both soils alike (seeds 0-3: 0.428 against 0.476 by mass).

    On the four seeds' mean, not on seed 0 alone: session 33's sleep rule (grains kept awake
    while the machine touches them, docs/soil_models.md "Speed") left the four seeds' mean
    at 0.414 but moved seed 0 from 0.467 to 0.363 (the seeds scatter 0.36-0.49). ~1 min of
    CPU."""
    style = {"impact_cue": "stall", "push_again": True}
    particles = np.mean([expert_fill("summer", "particles", style, seed) for seed in STALL_SEEDS])
    mouth = np.mean(
        [
            expert_fill("summer", "heightfield", style, seed, soil_options={"intake": "mouth"})
            for seed in STALL_SEEDS
        ]
    )
    assert abs(particles / mouth - 1.0) <= AGREEMENT  # 0.414 / 0.476 in session 33


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
