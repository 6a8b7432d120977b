"""The pile loader's constructor options as configs may set them (a plain dataclass).

pilerl reads the fields (names, types, defaults) to build its typed ``env`` settings, so
``env.soil=particles`` is checked when the config is composed; ``__post_init__`` checks
the values. Errors start with the field's name (pilerl prefixes ``env.``). Other
constructor arguments of ``PileLoadingEnv`` (machine, pile, bucket, task, reward_weights,
render_mode, render_size, camera) are for Python callers and rendering, not configs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

MAX_ANGLE_DEG = 90.0  # approach angles beyond this face away from the pile


@dataclass
class PileLoaderOptions:
    """Keyword options of ``PileLoadingEnv`` (see its docstring for each one's meaning).

    Attributes:
        condition: condition preset (``summer``, ``winter_a`` .. ``winter_d``).
        soil: soil model (``heightfield`` or ``particles``).
        soil_options: keyword options of the soil model (e.g. ``{max_particles: 350}``).
        condition_overrides: changes to the condition's physical values, by part and field
            (e.g. ``{ground: {tyre_friction: 0.08}}``).
        control_hz: control rate [Hz].
        physics_hz: physics rate [Hz] (>= 500).
        sensor_noise: multiplier of the sensors' default noise (0 = noiseless).
        start_distance_range_m: cutting edge to pile toe at reset [m], (low, high).
        approach_angle_range_deg: heading relative to the pile normal [deg], (low, high).
        actuation_latency_s: dead time from a command to the valves and the pump [s],
            (low, high): drawn per episode (low = high: a fixed delay; the real machine:
            0.1-0.3 s).
    """

    condition: str = "summer"
    soil: str = "heightfield"
    soil_options: dict[str, Any] = field(default_factory=dict)
    condition_overrides: dict[str, dict[str, float]] = field(default_factory=dict)
    control_hz: float = 20.0
    physics_hz: float = 500.0
    sensor_noise: float = 1.0
    start_distance_range_m: list[float] = field(default_factory=lambda: [1.0, 5.0])
    approach_angle_range_deg: list[float] = field(default_factory=lambda: [-10.0, 10.0])
    actuation_latency_s: list[float] = field(default_factory=lambda: [0.0, 0.0])

    def __post_init__(self) -> None:
        for name in ("condition", "soil"):
            if not (isinstance(getattr(self, name), str) and getattr(self, name)):
                raise ValueError(f"{name}: must be a non-empty name, got {getattr(self, name)!r}")
        for name in ("control_hz", "physics_hz"):
            _positive(name, getattr(self, name))
        if self.physics_hz < self.control_hz:
            raise ValueError(
                f"physics_hz ({self.physics_hz}) must be >= control_hz ({self.control_hz}): "
                "each control step runs at least one physics step"
            )
        if not (math.isfinite(self.sensor_noise) and self.sensor_noise >= 0):
            raise ValueError(f"sensor_noise: must be finite and >= 0, got {self.sensor_noise}")
        _interval("start_distance_range_m", self.start_distance_range_m, 0.0, math.inf)
        _interval(
            "approach_angle_range_deg", self.approach_angle_range_deg, -MAX_ANGLE_DEG, MAX_ANGLE_DEG
        )
        _interval("actuation_latency_s", self.actuation_latency_s, 0.0, 1.0)
        for part, values in self.condition_overrides.items():
            if not isinstance(values, dict):
                raise ValueError(f"condition_overrides.{part}: must map fields to numbers")
            for key, value in values.items():
                if not (isinstance(value, int | float) and math.isfinite(value)):
                    raise ValueError(
                        f"condition_overrides.{part}.{key}: must be finite, got {value!r}"
                    )


def _positive(name: str, value: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
        raise ValueError(f"{name}: must be a finite number > 0, got {value!r}")


def _interval(name: str, value: list[float], low: float, high: float) -> None:
    if len(value) != 2 or not all(math.isfinite(v) for v in value):
        raise ValueError(f"{name}: must be two finite numbers [low, high], got {list(value)}")
    if not (low <= value[0] <= value[1] <= high):
        raise ValueError(f"{name}: must satisfy {low} <= low <= high <= {high}, got {list(value)}")
