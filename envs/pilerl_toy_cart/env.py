"""ToyCart-v0: push a 1-D cart [m] to a target and stop there; dt = 0.05 s."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

MASS_KG = 10.0
MAX_FORCE_N = 20.0
TARGET_M = 1.0
MAX_STEPS = 100


class ToyCartEnv(gym.Env):
    """Observation: ``position`` [m] and ``velocity`` [m/s]; action: force fraction in [-1, 1]."""

    metadata = {"render_modes": [], "render_fps": 20}
    dt = 0.05

    def __init__(self) -> None:
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
        return self._obs(), {}

    def step(self, action):
        if self._episode_over:
            raise RuntimeError(
                "ToyCartEnv.step: the episode has ended (terminated or truncated) or was never "
                "started; call reset() before stepping again"
            )
        u = np.asarray(action, dtype=np.float64)
        if u.shape != (1,) or not np.isfinite(u).all():
            raise ValueError(f"ToyCartEnv.step: action must be 1 finite value, got {action!r}")
        force = float(np.clip(u[0], -1.0, 1.0)) * MAX_FORCE_N
        self._v = float(np.clip(self._v + force / MASS_KG * self.dt, -10.0, 10.0))
        self._x = float(np.clip(self._x + self._v * self.dt, -10.0, 10.0))
        self._steps += 1
        error = abs(self._x - TARGET_M)
        terminated = error < 0.05 and abs(self._v) < 0.05
        truncated = self._steps >= MAX_STEPS
        self._episode_over = terminated or truncated
        return self._obs(), -error, terminated, truncated, {"error_m": error}

    def _obs(self):
        return {
            "position": np.array([self._x], np.float32),
            "velocity": np.array([self._v], np.float32),
        }
