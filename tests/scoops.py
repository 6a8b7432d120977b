"""Shared test helper: run one scripted scoop and keep what the tests look at."""

from __future__ import annotations

from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np

import pilerl  # noqa: F401  (registers pilerl/PileLoading-v0)
from pilerl.operators import OperatorStyle, ScriptedScoopOperator

SENSIBLE = OperatorStyle()
EARLY_BOOM = OperatorStyle(early_boom_rise_s=0.5)
NO_BOOM = OperatorStyle(trigger_pressure_mpa=1000.0)  # the trigger never fires: pushes on


@dataclass
class Scoop:
    info: dict
    sensors: dict[str, list[float]] = field(default_factory=dict)
    depth_m: list[float] = field(default_factory=list)
    fill: list[float] = field(default_factory=list)
    mass_error_kg: list[float] = field(default_factory=list)
    rewards: list[float] = field(default_factory=list)
    reward_part_sums: list[float] = field(default_factory=list)


def run_scoop(
    style: OperatorStyle,
    *,
    condition: str = "summer",
    seed: int = 0,
    max_seconds: float = 30.0,
    **env_kwargs,
) -> Scoop:
    env = gym.make("pilerl/PileLoading-v0", condition=condition, **env_kwargs)
    obs, info = env.reset(seed=seed)
    soil = env.unwrapped.soil
    operator = ScriptedScoopOperator(style, dt=env.unwrapped.dt)
    scoop = Scoop(info=info, sensors={k: [] for k in obs})
    while True:
        obs, reward, terminated, truncated, info = env.step(operator.act(obs))
        for name, value in obs.items():
            scoop.sensors[name].append(float(value[0]))
        scoop.depth_m.append(info["cutting_depth_m"])
        scoop.fill.append(info["fill_fraction"])
        total = soil.pile_mass_kg + soil.bucket_load_kg + soil.spilled_kg
        scoop.mass_error_kg.append(abs(total - soil.initial_mass_kg))
        scoop.rewards.append(reward)
        scoop.reward_part_sums.append(sum(v for k, v in info.items() if k.startswith("reward_")))
        if terminated or truncated or info["elapsed_s"] >= max_seconds:
            break
    scoop.info = info
    env.close()
    return scoop


def peak(values: list[float]) -> float:
    return float(np.max(values))
