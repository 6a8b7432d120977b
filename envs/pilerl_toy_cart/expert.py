"""The toy cart's scripted expert: a PD controller on the distance to the target."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .env import TARGET_M

GAINS = {"position_gain": 1.5, "velocity_gain": 2.0}  # force fraction per m, per m/s


class CartExpert:
    """``u = clip(position_gain * (target - x) - velocity_gain * v, -1, 1)``."""

    PHASES = ("drive", "hold")

    def __init__(self, *, position_gain: float, velocity_gain: float) -> None:
        self.position_gain, self.velocity_gain = position_gain, velocity_gain
        self.reset()

    def reset(self) -> None:
        self.phase = "drive"
        self.last_label = np.zeros(1, np.float32)

    def act(self, sensors: Mapping[str, float]) -> np.ndarray:
        x = float(np.asarray(sensors["position"]).reshape(-1)[0])
        v = float(np.asarray(sensors["velocity"]).reshape(-1)[0])
        error = TARGET_M - x
        self.phase = "hold" if abs(error) < 0.1 else "drive"
        u = self.position_gain * error - self.velocity_gain * v
        self.last_label = np.array([np.clip(u, -1.0, 1.0)], np.float32)
        return self.last_label


def make_expert(*, dt: float, rng: np.random.Generator | None = None, **options) -> CartExpert:
    """The nominal expert (``rng=None``) or one with gains drawn +-20% from ``rng``.

    Options: ``position_gain``, ``velocity_gain`` (the nominal gains).
    """
    unknown = sorted(set(options) - set(GAINS))
    if unknown:
        raise ValueError(f"toy cart expert: unknown option(s) {unknown}; known: {sorted(GAINS)}")
    gains = {**GAINS, **options}
    for name, value in gains.items():
        if not (isinstance(value, int | float) and np.isfinite(value) and value > 0):
            raise ValueError(f"{name}: must be a finite number > 0, got {value!r}")
    if rng is not None:
        gains = {name: value * float(rng.uniform(0.8, 1.2)) for name, value in gains.items()}
    return CartExpert(**gains)
