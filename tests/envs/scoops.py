"""Shared test helper: run one scripted scoop and keep what the tests look at."""

from __future__ import annotations

from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np
from pilerl_pile_loader.operator import make_expert

import pilerl  # noqa: F401  (registers pilerl/PileLoading-v0)

# the pile loader expert's nominal style, set by its options (``OperatorStyle`` fields)
SENSIBLE: dict = {}
EARLY_BOOM = {"jumpy": True, "impact_hold_s": 0.0}  # lifts on a false impact cue
NO_BOOM = {"impact_rise_mpa": 1000.0}  # never feels the impact: pushes on

# the pile loader's sensor readings at rest before the pile (rad, MPa): what the operator
# tests feed the expert by hand
REST = {
    "boom_angle": -0.45,
    "bucket_angle": 0.45,
    "drive_pressure": 4.0,
    "telescope_pressure": 0.8,
    "boom_pressure": 2.8,
    "bucket_pressure": 0.8,
    "pump_angle": 0.1,
}


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
    style: dict,
    *,
    condition: str = "summer",
    seed: int = 0,
    max_seconds: float = 30.0,
    **env_kwargs,
) -> Scoop:
    env = gym.make("pilerl/PileLoading-v0", condition=condition, **env_kwargs)
    obs, info = env.reset(seed=seed)
    soil = env.unwrapped.soil
    operator = make_expert(dt=env.unwrapped.dt, **style)
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


@dataclass
class DriveIn:
    """One drive at the pile with fixed commands: per-step readings and cutting depth."""

    sensors: dict[str, np.ndarray]
    depth_m: np.ndarray


def drive_in(
    condition: str,
    *,
    seed: int,
    throttle: float = 0.6,
    seconds: float = 8.0,
    then: tuple[float, float, float] | None = None,
    then_after_s: float = 0.0,
    **env_kwargs,
) -> DriveIn:
    """Drive at the pile with ``throttle``, boom and bucket held (issue #15's measurement);
    from ``then_after_s`` on, send the command ``then`` (boom, bucket, throttle) instead."""
    env = gym.make("pilerl/PileLoading-v0", condition=condition, **env_kwargs).unwrapped
    obs, info = env.reset(seed=seed)
    readings: dict[str, list[float]] = {k: [] for k in obs}
    depth = []
    while info["elapsed_s"] < seconds - 1e-9:
        late = then is not None and info["elapsed_s"] >= then_after_s - 1e-9
        action = then if late else (0.0, 0.0, throttle)
        obs, _, terminated, truncated, info = env.step(np.asarray(action, dtype=np.float32))
        for name, value in obs.items():
            readings[name].append(float(value[0]))
        depth.append(info["cutting_depth_m"])
        if terminated or truncated:
            break
    env.close()
    return DriveIn({k: np.array(v) for k, v in readings.items()}, np.array(depth))
