"""The particle pile's sleeping (``ParticleSoil``, module docstring "Sleeping"): no grain
falls asleep while the machine touches the pile, since every tree MuJoCo puts to sleep
makes it recompute the whole physics step; the pile still sleeps at reset and between
episodes; ``sleep_in_contact=True`` keeps the old behaviour (grains fall asleep while the
bucket digs).

On the coarse pile (4 grains across the mouth) to keep it fast."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import pilerl  # noqa: F401

DRIVE_IN = np.array([0.0, 0.0, 0.5], np.float32)  # half throttle, bucket flat
DRIVE_STEPS = 48  # 2.4 s at 20 Hz: 1 m to the toe, then into the pile until it stalls


def make(**options) -> gym.Env:
    return gym.make(
        "pilerl/PileLoading-v0",
        soil="particles",
        sensor_noise=0.0,
        start_distance_range_m=(1.0, 1.0),
        approach_angle_range_deg=(0.0, 0.0),
        soil_options={"mouth_grains": 4.0, **options},
    )


def drive_in(env: gym.Env) -> tuple[int, int]:
    """Drive into the pile from seed 0, watching every soil update: the physics chunks run
    (between two updates) after an update that found the machine touching a grain, and how
    many of those put a grain to sleep."""
    soil = env.unwrapped.soil
    data, trees = env.unwrapped.data, soil._grain_trees
    chunks = {"touched": 0, "slept": 0}
    last: list = []  # (touching at the last update, grains asleep then)
    update = soil.update

    def watched(dt: float) -> None:
        if last and last[0][0]:
            chunks["touched"] += 1
            chunks["slept"] += int(((data.tree_asleep[trees] >= 0) & ~last[0][1]).any())
        update(dt)
        last[:] = [(soil.machine_touches_a_grain(), data.tree_asleep[trees] >= 0)]

    soil.update = watched
    try:
        env.reset(seed=0)
        for _ in range(DRIVE_STEPS):
            env.step(DRIVE_IN)
    finally:
        del soil.update
    return chunks["touched"], chunks["slept"]


@pytest.fixture(scope="module")
def env() -> gym.Env:
    return make()


def test_the_pile_sleeps_after_reset(env):
    sim = env.unwrapped
    env.reset(seed=0)
    env.step(np.zeros(3, np.float32))  # 0.05 s: more than MuJoCo's 10 steps at rest
    assert not sim.data.tree_awake[sim.soil._grain_trees].any()


def test_no_grain_falls_asleep_while_the_machine_touches_the_pile(env):
    touched, slept = drive_in(env)
    assert touched >= 20  # the bucket was in the pile
    assert slept == 0
    # and once the machine has left, the grains may sleep again (their compiled policy)
    sim = env.unwrapped
    env.reset(seed=0)
    policy = sim.model.tree_sleep_policy[sim.soil._grain_trees]
    assert (policy == sim.soil._grain_sleep_policy).all()
    assert (policy != mujoco.mjtSleepPolicy.mjSLEEP_NEVER).all()


def test_grains_fell_asleep_in_contact_before_session_33():
    """Without the rule (``sleep_in_contact=True``) grains fall asleep while the bucket is
    in the pile: what made each such physics step cost two."""
    touched, slept = drive_in(make(sleep_in_contact=True))
    assert touched >= 20
    assert slept > 0


@pytest.mark.parametrize("bad", [1, "yes", None])
def test_sleep_in_contact_must_be_a_bool(bad):
    with pytest.raises(ValueError, match="sleep_in_contact"):
        make(sleep_in_contact=bad)
