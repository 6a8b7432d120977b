"""Working conditions: the pile material, the ground under the tyres and the oil temperature.

A condition preset bundles the three. ``summer`` is the paper's training condition (dry
gravel on a dry site); ``winter_a`` .. ``winter_d`` follow the paper's Fig. 1 test days:

- A: cold wet weather (wet gravel, muddy ground)
- B: mild icy surface with partial snow
- C: icy surface, snow covering the surface and the pile
- D: cold winter, gravel partly replaced by snow clearing (snow as the material)

``HELD_OUT`` holds conditions the paper could not test (``wet_clay``, ``frozen_crust``,
``dry_sand``): a condition-shift suite that no demonstration or curriculum uses by
default (the plugin declares them as its ``held_out`` group, kept out of ``all``).

Numbers are typical textbook values, not measurements of the paper's site; the sources are
listed in docs/machine_model.md (held-out presets: docs/env_card.md). Every field is
validated, so a typo'd or impossible value fails at construction with the field's name.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field


def _require(condition: bool, where: str, message: str) -> None:
    if not condition:
        raise ValueError(f"{where}: {message}")


def _require_finite(obj: object) -> None:
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if isinstance(value, float | int) and not math.isfinite(value):
            raise ValueError(f"{type(obj).__name__}.{f.name}: must be finite, got {value!r}")


@dataclass(frozen=True)
class Material:
    """Pile material: what the bucket cuts and carries.

    Attributes:
        name: human-readable description.
        density_kg_m3: loose bulk density of the material in the pile [kg/m^3].
        friction_angle_deg: internal friction angle phi; also the angle of repose of the
            pile face [deg].
        cohesion_pa: cohesion c [Pa]; zero for dry gravel, large for frozen lumps.
        tool_friction_angle_deg: soil-steel friction angle delta [deg].
        grain_size_m: representative grain diameter [m]; sets the particle radius of the
            particle soil model and the roughness of the pile surface.
    """

    name: str
    density_kg_m3: float
    friction_angle_deg: float
    cohesion_pa: float
    tool_friction_angle_deg: float
    grain_size_m: float

    def __post_init__(self) -> None:
        _require_finite(self)
        where = f"Material({self.name!r})"
        _require(
            100.0 <= self.density_kg_m3 <= 3000.0,
            f"{where}.density_kg_m3",
            f"must lie in [100, 3000] kg/m^3, got {self.density_kg_m3}",
        )
        _require(
            5.0 <= self.friction_angle_deg <= 60.0,
            f"{where}.friction_angle_deg",
            f"must lie in [5, 60] deg, got {self.friction_angle_deg}",
        )
        _require(
            self.cohesion_pa >= 0.0,
            f"{where}.cohesion_pa",
            f"must be >= 0 Pa, got {self.cohesion_pa}",
        )
        _require(
            0.0 <= self.tool_friction_angle_deg <= self.friction_angle_deg,
            f"{where}.tool_friction_angle_deg",
            f"must lie in [0, friction_angle_deg] deg, got {self.tool_friction_angle_deg}",
        )
        _require(
            0.001 <= self.grain_size_m <= 0.2,
            f"{where}.grain_size_m",
            f"must lie in [0.001, 0.2] m, got {self.grain_size_m}",
        )


@dataclass(frozen=True)
class Ground:
    """The surface the tyres drive on.

    Attributes:
        tyre_friction: Coulomb friction coefficient tyre/ground (dimensionless).
        rolling_resistance: rolling-resistance coefficient (resistive force / normal load).
    """

    tyre_friction: float
    rolling_resistance: float

    def __post_init__(self) -> None:
        _require_finite(self)
        _require(
            0.02 <= self.tyre_friction <= 1.5,
            "Ground.tyre_friction",
            f"must lie in [0.02, 1.5], got {self.tyre_friction}",
        )
        _require(
            0.0 <= self.rolling_resistance <= 0.3,
            "Ground.rolling_resistance",
            f"must lie in [0, 0.3], got {self.rolling_resistance}",
        )


@dataclass(frozen=True)
class Hydraulics:
    """Oil-temperature effects on the hydraulic system.

    Attributes:
        oil_temperature_c: hydraulic oil temperature [deg C] (documentation only).
        valve_lag_s: first-order time constant of the boom and bucket valve response [s];
            cold, viscous oil makes it slower.
        pump_lag_s: first-order time constant of the HST swash plate following the drive
            command [s] (the pump ramps; cold oil ramps slower).
        speed_scale: fraction of the rated cylinder and drive speeds reached (viscous losses).
    """

    oil_temperature_c: float
    valve_lag_s: float
    pump_lag_s: float
    speed_scale: float

    def __post_init__(self) -> None:
        _require_finite(self)
        _require(
            0.0 < self.valve_lag_s <= 2.0,
            "Hydraulics.valve_lag_s",
            f"must lie in (0, 2] s, got {self.valve_lag_s}",
        )
        _require(
            0.0 < self.pump_lag_s <= 5.0,
            "Hydraulics.pump_lag_s",
            f"must lie in (0, 5] s, got {self.pump_lag_s}",
        )
        _require(
            0.1 <= self.speed_scale <= 1.0,
            "Hydraulics.speed_scale",
            f"must lie in [0.1, 1], got {self.speed_scale}",
        )


@dataclass(frozen=True)
class Condition:
    """A named working condition: material + ground + hydraulics."""

    name: str
    description: str
    material: Material
    ground: Ground
    hydraulics: Hydraulics = field(default_factory=lambda: WARM_OIL)

    def with_overrides(self, overrides: dict[str, dict[str, float]] | None) -> Condition:
        """Return a copy with fields replaced, e.g. ``{"material": {"density_kg_m3": 1500}}``.

        Unknown sections or fields fail with the list of valid ones.
        """
        if not overrides:
            return self
        parts = {"material": self.material, "ground": self.ground, "hydraulics": self.hydraulics}
        for section, values in overrides.items():
            if section not in parts:
                raise ValueError(
                    f"condition override: unknown section {section!r}; known: {sorted(parts)}"
                )
            valid = {f.name for f in dataclasses.fields(parts[section])}
            unknown = set(values) - valid
            if unknown:
                raise ValueError(
                    f"condition override {section}: unknown field(s) {sorted(unknown)}; "
                    f"known: {sorted(valid)}"
                )
            parts[section] = dataclasses.replace(parts[section], **values)
        return dataclasses.replace(self, **parts)


WARM_OIL = Hydraulics(oil_temperature_c=45.0, valve_lag_s=0.08, pump_lag_s=0.5, speed_scale=1.0)

DRY_GRAVEL = Material(
    name="dry gravel 0-32 mm",
    density_kg_m3=1700.0,
    friction_angle_deg=38.0,
    cohesion_pa=0.0,
    tool_friction_angle_deg=25.0,
    grain_size_m=0.02,
)

CONDITIONS: dict[str, Condition] = {
    "summer": Condition(
        name="summer",
        description="Dry gravel on a dry, firm site; warm oil (the paper's training data).",
        material=DRY_GRAVEL,
        ground=Ground(tyre_friction=0.75, rolling_resistance=0.03),
        hydraulics=WARM_OIL,
    ),
    "winter_a": Condition(
        name="winter_a",
        description="A: cold wet weather; wet gravel, muddy ground.",
        material=Material("wet gravel", 1950.0, 34.0, 4000.0, 22.0, 0.02),
        ground=Ground(tyre_friction=0.50, rolling_resistance=0.07),
        hydraulics=Hydraulics(
            oil_temperature_c=5.0, valve_lag_s=0.15, pump_lag_s=0.6, speed_scale=0.90
        ),
    ),
    "winter_b": Condition(
        name="winter_b",
        description="B: mild icy surface with partial snow; moist gravel.",
        material=Material("moist gravel", 1800.0, 36.0, 2500.0, 22.0, 0.02),
        ground=Ground(tyre_friction=0.22, rolling_resistance=0.03),
        hydraulics=Hydraulics(
            oil_temperature_c=-2.0, valve_lag_s=0.20, pump_lag_s=0.7, speed_scale=0.85
        ),
    ),
    "winter_c": Condition(
        name="winter_c",
        description="C: icy surface, snow covering the surface and the pile.",
        material=Material("gravel under snow", 1550.0, 33.0, 2000.0, 15.0, 0.02),
        # snow-covered ice under lugged tyres: 0.2-0.3 (docs/machine_model.md); bare wet
        # ice would be ~0.1
        ground=Ground(tyre_friction=0.20, rolling_resistance=0.04),
        hydraulics=Hydraulics(
            oil_temperature_c=-8.0, valve_lag_s=0.25, pump_lag_s=0.8, speed_scale=0.80
        ),
    ),
    "winter_d": Condition(
        name="winter_d",
        description="D: cold winter; snow (from snow clearing) instead of gravel, packed snow.",
        material=Material("wet packed snow", 500.0, 30.0, 6000.0, 10.0, 0.01),
        ground=Ground(tyre_friction=0.30, rolling_resistance=0.05),
        hydraulics=Hydraulics(
            oil_temperature_c=-15.0, valve_lag_s=0.35, pump_lag_s=1.0, speed_scale=0.75
        ),
    ),
}


# Held-out conditions: beyond the paper's test days, for a condition-shift test. Values
# and their sources: docs/env_card.md ("Held-out conditions").
HELD_OUT: dict[str, Condition] = {
    "wet_clay": Condition(
        name="wet_clay",
        description="Held out: wet heavy clay on soft, rutted ground; cool oil.",
        material=Material("wet sandy clay", 1850.0, 22.0, 12000.0, 14.0, 0.001),
        ground=Ground(tyre_friction=0.40, rolling_resistance=0.12),
        hydraulics=Hydraulics(
            oil_temperature_c=10.0, valve_lag_s=0.12, pump_lag_s=0.55, speed_scale=0.95
        ),
    ),
    "frozen_crust": Condition(
        name="frozen_crust",
        description="Held out: a frozen crust over loose gravel, on frozen ground; cold oil.",
        # one soil layer: the crust is an effective cohesion over the cut depth
        material=Material("loose gravel under a frozen crust", 1600.0, 36.0, 15000.0, 20.0, 0.02),
        ground=Ground(tyre_friction=0.25, rolling_resistance=0.02),
        hydraulics=Hydraulics(
            oil_temperature_c=-10.0, valve_lag_s=0.28, pump_lag_s=0.85, speed_scale=0.78
        ),
    ),
    "dry_sand": Condition(
        name="dry_sand",
        description="Held out: dry fine sand on loose sand; hot oil.",
        material=Material("dry fine sand", 1450.0, 32.0, 0.0, 20.0, 0.001),
        ground=Ground(tyre_friction=0.30, rolling_resistance=0.10),
        hydraulics=Hydraulics(
            oil_temperature_c=65.0, valve_lag_s=0.07, pump_lag_s=0.45, speed_scale=1.0
        ),
    ),
}

PRESETS: dict[str, Condition] = {**CONDITIONS, **HELD_OUT}  # every preset a name can pick


def get_condition(name: str) -> Condition:
    """Look up a condition preset (the paper's or a held-out one) by name; unknown names
    list the known ones."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(
            f"unknown condition {name!r}; known conditions: {sorted(PRESETS)}"
        ) from None


def parse_overrides(text: str) -> dict[str, dict[str, float]]:
    """Condition overrides from a JSON text as a command line gives them, e.g.
    ``'{"material": {"cohesion_pa": 0}}'``, checked against the summer preset's fields and
    ranges; raises ``ValueError`` naming what is wrong (not JSON, not an object of objects,
    an unknown part or field, a value that is not a finite number or out of range)."""
    try:
        overrides = json.loads(text)
    except json.JSONDecodeError as error:
        raise ValueError(f"condition overrides: not JSON ({error}): {text!r}") from None
    example = '{"material": {"cohesion_pa": 0}}'
    if not isinstance(overrides, dict) or not all(isinstance(v, dict) for v in overrides.values()):
        raise ValueError(f"condition overrides: expected an object like {example}, got {text!r}")
    for part, values in overrides.items():
        for name, value in values.items():
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"condition overrides {part}.{name}: not a number: {value!r}")
    CONDITIONS["summer"].with_overrides(overrides)
    return overrides


def overrides_argument(text: str) -> dict[str, dict[str, float]]:
    """``parse_overrides`` as an argparse ``type``: a bad text is a parser error that names
    the problem (argparse hides a plain ``ValueError``'s message)."""
    import argparse

    try:
        return parse_overrides(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
