"""The scoop task: when an episode ends, whether it succeeded, and the named reward parts."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class ScoopTask:
    """Episode rules for one scoop.

    Attributes:
        success_fill_fraction: the paper's half-full rule [fraction of rated capacity].
        curled_pitch_rad: bucket floor pitch above horizontal that counts as curled back.
        raised_hinge_height_m: bucket hinge height above ground that counts as raised [m].
        max_episode_seconds: simulated time after which the episode is truncated [s].
        max_frame_tilt_rad: front-frame tilt beyond which the machine has tipped [rad].
    """

    success_fill_fraction: float = 0.5
    curled_pitch_rad: float = 0.45
    raised_hinge_height_m: float = 1.0
    max_episode_seconds: float = 30.0
    max_frame_tilt_rad: float = 0.6

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"ScoopTask.{name}: must be finite and > 0, got {value}")


@dataclass(frozen=True)
class RewardWeights:
    """Weights of the reward parts; ``reward = sum`` of the weighted parts.

    Attributes:
        fill: per unit increase of fill fraction.
        spill: per unit of spilled mass, as a fraction of the rated load mass (a penalty).
        time: per simulated second (a penalty).
        energy: per kJ of hydraulic work (a penalty).
        success: once, when a scoop ends curled and raised at least half full.
    """

    fill: float = 1.0
    spill: float = 1.0
    time: float = 0.02
    energy: float = 0.002
    success: float = 1.0

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"RewardWeights.{name}: must be finite and >= 0, got {value}")


def reward_parts(
    weights: RewardWeights,
    *,
    fill_gain: float,
    spilled_fraction_gain: float,
    seconds: float,
    work_kj: float,
    succeeded: bool,
) -> dict[str, float]:
    """The named parts of one step's reward (already weighted and signed)."""
    return {
        "reward_fill": weights.fill * fill_gain,
        "reward_spill": -weights.spill * spilled_fraction_gain,
        "reward_time": -weights.time * seconds,
        "reward_energy": -weights.energy * work_kj,
        "reward_success": weights.success * float(succeeded),
    }
