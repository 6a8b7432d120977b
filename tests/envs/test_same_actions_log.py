"""benchmarks/same_actions.py logs the drive pressure at every physics step of an episode."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import gymnasium as gym
import numpy as np

import pilerl  # noqa: F401  (registers pilerl/PileLoading-v0)

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "same_actions.py"


def test_the_physics_rate_log_has_every_physics_step_and_lets_the_soil_go():
    spec = importlib.util.spec_from_file_location("same_actions", SCRIPT)
    same_actions = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(same_actions)
    env = gym.make("pilerl/PileLoading-v0", sensor_noise=0.0)
    sim = env.unwrapped

    trace = same_actions.episode(
        env, 0, lambda step, obs: np.array([0.0, 0.0, 0.5], np.float32), max_s=0.5
    )

    steps = len(trace["action"])
    assert steps == 10
    assert len(same_actions.LOG.p_d) == steps * sim.frame_skip
    assert len(same_actions.LOG.speed) == steps * sim.frame_skip
    assert same_actions.LOG.speed[-1] > 0.0  # driving at half throttle: the log moves
    assert "advance" not in vars(sim.soil)  # the soil steps through its own method again
    env.close()
