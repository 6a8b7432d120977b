"""The simulator's settings (``EnvConfig``, the ``env`` config group).

They belong to the simulator room (``pilerl/sim``) and move there with the simulator
contract; until then every room imports them from here, and tests/test_layers.py counts this
module on the simulator's floor (it imports only ``pilerl.checks`` and ``pilerl.sim``).
Recipes turn the config into plain library arguments once, at their boundary
(``EnvConfig.make_kwargs``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from pilerl import checks

MAX_ANGLE_DEG = 90.0  # approach angles beyond this face away from the pile


@dataclass
class EnvConfig:
    """Which simulator to build and with what arguments.

    Attributes:
        simulator: plugin name (``pile_loader``, ``toy_cart``...).
        condition: condition preset (``summer``, ``winter_a`` .. ``winter_d``).
        soil: soil model (``heightfield`` or ``particles``).
        soil_options: keyword options of the soil model (e.g. ``{max_particles: 350}``).
        condition_overrides: changes to the condition's physical values, by part and field
            (e.g. ``{ground: {tyre_friction: 0.08}}``); checked by the simulator.
        control_hz: control rate [Hz].
        physics_hz: physics rate [Hz] (>= 500).
        sensor_noise: multiplier of the sensors' default noise (0 = noiseless).
        start_distance_range_m: cutting edge to pile toe at reset [m], (low, high).
        approach_angle_range_deg: heading relative to the pile normal [deg], (low, high).
    """

    simulator: str = "pile_loader"
    condition: str = "summer"
    soil: str = "heightfield"
    soil_options: dict[str, Any] = field(default_factory=dict)
    condition_overrides: dict[str, dict[str, float]] = field(default_factory=dict)
    control_hz: float = 20.0
    physics_hz: float = 500.0
    sensor_noise: float = 1.0
    start_distance_range_m: list[float] = field(default_factory=lambda: [1.0, 5.0])
    approach_angle_range_deg: list[float] = field(default_factory=lambda: [-10.0, 10.0])

    def __post_init__(self) -> None:
        from pilerl.sim import available_simulators

        checks.one_of("env.simulator", self.simulator, available_simulators())
        checks.name("env.condition", self.condition)
        checks.name("env.soil", self.soil)
        checks.positive("env.control_hz", self.control_hz)
        checks.positive("env.physics_hz", self.physics_hz)
        if self.physics_hz < self.control_hz:
            raise ValueError(
                f"env.physics_hz ({self.physics_hz}) must be >= env.control_hz "
                f"({self.control_hz}): each control step runs at least one physics step"
            )
        checks.non_negative("env.sensor_noise", self.sensor_noise)
        checks.interval("env.start_distance_range_m", self.start_distance_range_m, low=0.0)
        checks.interval(
            "env.approach_angle_range_deg",
            self.approach_angle_range_deg,
            low=-MAX_ANGLE_DEG,
            high=MAX_ANGLE_DEG,
        )
        for part, values in self.condition_overrides.items():
            if not isinstance(values, dict):
                raise ValueError(f"env.condition_overrides.{part}: must map fields to numbers")
            for key, value in values.items():
                checks.finite(f"env.condition_overrides.{part}.{key}", value)

    def make_kwargs(self, **overrides) -> dict:
        """Keyword arguments for ``pilerl.sim.make_gym_env`` (simulator name excluded)."""
        kwargs = {k: v for k, v in asdict(self).items() if k != "simulator"}
        if not kwargs["condition_overrides"]:  # simulators without conditions need not know it
            del kwargs["condition_overrides"]
        kwargs["start_distance_range_m"] = tuple(kwargs["start_distance_range_m"])
        kwargs["approach_angle_range_deg"] = tuple(kwargs["approach_angle_range_deg"])
        kwargs.update(overrides)
        return kwargs
