"""Actuation latency: a command reaches the valves and the pump some time after it is given.

The real machine ran its controller at 3 Hz and executed commands 0.1-0.3 s late (CAN,
UDP and the by-wire controllers between the PC and the valves; the paper's "Controller
hardware"). ``ActuationDelay`` is that dead time, at physics-step resolution: each control
step is cut into segments, each driven by the command that has arrived by then.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence

import numpy as np

MAX_LATENCY_S = 2.0


class ActuationDelay:
    """Dead time between a command and the actuators.

    Args:
        latency_s: the delay [s], or a range ``(low, high)`` drawn uniformly at each reset.
        physics_dt: physics step [s]. frame_skip: physics steps per control step.
        n_controls: size of a command (the machine starts each episode at rest: zeros
            act until the first command arrives).
    """

    def __init__(
        self,
        latency_s: float | Sequence[float],
        *,
        physics_dt: float,
        frame_skip: int,
        n_controls: int,
    ) -> None:
        low, high = _latency_range(latency_s)
        self.range_s = (low, high)
        self.physics_dt, self.frame_skip, self.n_controls = physics_dt, frame_skip, n_controls
        self.latency_s = low
        self.reset(None)

    @property
    def enabled(self) -> bool:
        return self.range_s[1] > 0

    def reset(self, rng: np.random.Generator | None) -> None:
        """Start an episode: nothing pending; draws the latency if a range was given."""
        low, high = self.range_s
        if rng is not None and high > low:
            self.latency_s = float(rng.uniform(low, high))
        self._delay_steps = round(self.latency_s / self.physics_dt)
        self._now = 0  # physics steps since reset
        self._active = np.zeros(self.n_controls)
        self._pending: deque[tuple[int, np.ndarray]] = deque()

    def segments(self, command: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """Give ``command`` now; returns the next control step as (physics steps, command
        acting) segments, in order, summing to ``frame_skip``."""
        self._pending.append((self._now + self._delay_steps, np.array(command, dtype=float)))
        end = self._now + self.frame_skip
        out, cursor = [], self._now
        while self._pending and self._pending[0][0] < end:
            arrives, arrived = self._pending.popleft()
            if arrives > cursor:
                out.append((arrives - cursor, self._active))
                cursor = arrives
            self._active = arrived
        out.append((end - cursor, self._active))
        self._now = end
        return [(n, c) for n, c in out if n > 0]


def _latency_range(latency_s: float | Sequence[float]) -> tuple[float, float]:
    values = [latency_s, latency_s] if isinstance(latency_s, int | float) else list(latency_s)
    if len(values) != 2 or not all(
        isinstance(v, int | float) and math.isfinite(v) and 0 <= v <= MAX_LATENCY_S for v in values
    ):
        raise ValueError(
            f"actuation_latency_s: must be a delay in [0, {MAX_LATENCY_S}] s or a range "
            f"(low, high) of such delays, got {latency_s!r}"
        )
    if values[0] > values[1]:
        raise ValueError(f"actuation_latency_s: low must be <= high, got {latency_s!r}")
    return float(values[0]), float(values[1])
