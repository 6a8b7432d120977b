"""ToyCart-v0: push a 1-D cart [m] to a target and stop there within 5 s."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .options import CONDITIONS, ToyCartOptions

MAX_FORCE_N = 20.0
TARGET_M = 1.0
EPISODE_SECONDS = 5.0
DEFAULT_CONTROL_HZ = 20.0
MAX_STEPS = round(EPISODE_SECONDS * DEFAULT_CONTROL_HZ)  # steps of an episode at 20 Hz
STOP_TOLERANCE = 0.05  # |position error| [m] and |velocity| [m/s] that count as stopped


class ToyCartEnv(gym.Env):
    """Observation: ``position`` [m] and ``velocity`` [m/s]; action: force fraction in [-1, 1].

    Reward: ``reward_distance`` (minus the distance to the target [m]) plus
    ``reward_success`` (1 when the cart stops at the target), both in ``info``.

    Args:
        condition: ``nominal``, ``heavy`` or ``headwind`` (``options.CONDITIONS``).
        control_hz: control rate [Hz]; an episode is truncated after 5 s.
    """

    metadata = {"render_modes": [], "render_fps": 20}

    def __init__(self, condition: str = "nominal", control_hz: float = DEFAULT_CONTROL_HZ) -> None:
        options = ToyCartOptions(condition=condition, control_hz=control_hz)
        self.condition = options.condition
        self.mass_kg, self.opposing_force_n = CONDITIONS[options.condition]
        self.dt = 1.0 / options.control_hz
        self.max_steps = round(EPISODE_SECONDS / self.dt)
        self.metadata = {**self.metadata, "render_fps": options.control_hz}
        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self.observation_space = spaces.Dict(
            {
                "position": spaces.Box(-10.0, 10.0, shape=(1,), dtype=np.float32),
                "velocity": spaces.Box(-10.0, 10.0, shape=(1,), dtype=np.float32),
            }
        )
        self._episode_over = True  # no episode until reset(): step() refuses

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self._x, self._v, self._steps = float(self.np_random.uniform(-1.0, 0.0)), 0.0, 0
        self._episode_over = False
        return self._obs(), {"start_position_m": self._x, **self._info(success=False)}

    def step(self, action):
        if self._episode_over:
            raise RuntimeError(
                "ToyCartEnv.step: the episode has ended (terminated or truncated) or was never "
                "started; call reset() before stepping again"
            )
        u = np.asarray(action, dtype=np.float64)
        if u.shape != (1,) or not np.isfinite(u).all():
            raise ValueError(f"ToyCartEnv.step: action must be 1 finite value, got {action!r}")
        force = float(np.clip(u[0], -1.0, 1.0)) * MAX_FORCE_N - self.opposing_force_n
        self._v = float(np.clip(self._v + force / self.mass_kg * self.dt, -10.0, 10.0))
        self._x = float(np.clip(self._x + self._v * self.dt, -10.0, 10.0))
        self._steps += 1
        error = abs(self._x - TARGET_M)
        terminated = error < STOP_TOLERANCE and abs(self._v) < STOP_TOLERANCE
        truncated = self._steps >= self.max_steps
        self._episode_over = terminated or truncated
        info = self._info(success=terminated)
        reward = info["reward_distance"] + info["reward_success"]
        return self._obs(), reward, terminated, truncated, info

    def _info(self, *, success: bool) -> dict:
        error = abs(self._x - TARGET_M)
        return {
            "error_m": error,
            "success": success,
            "reward_distance": -error,
            "reward_success": float(success),
        }

    def _obs(self):
        return {
            "position": np.array([self._x], np.float32),
            "velocity": np.array([self._v], np.float32),
        }
