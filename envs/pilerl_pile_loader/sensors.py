"""The seven sensors of the paper's Table I, by name, with units, ranges and noise.

Configs choose controller inputs ``s`` and attention inputs ``s'`` by these names.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Sensor:
    """One named sensor channel.

    Attributes:
        name: observation key.
        symbol: the paper's symbol.
        unit: physical unit of the reading.
        low, high: range of the reading; noisy readings saturate here like a real transducer.
        noise_std: default standard deviation of additive Gaussian noise, in ``unit``.
        description: what it measures.
    """

    name: str
    symbol: str
    unit: str
    low: float
    high: float
    noise_std: float
    description: str


SENSORS: tuple[Sensor, ...] = (
    Sensor("boom_angle", "theta1", "rad", -0.55, 1.05, 0.002, "boom joint angle"),
    Sensor("bucket_angle", "theta2", "rad", -1.1, 1.5, 0.002, "bucket joint angle"),
    Sensor(
        "drive_pressure",
        "p_d",
        "MPa",
        0.0,
        40.0,
        0.15,
        "hydraulic drive transmission (HST) pressure",
    ),
    Sensor(
        "telescope_pressure",
        "p_t",
        "MPa",
        0.0,
        40.0,
        0.10,
        "hydraulic pressure at the telescope joint",
    ),
    Sensor("boom_pressure", "p_l", "MPa", 0.0, 40.0, 0.10, "hydraulic pressure at the boom joint"),
    Sensor(
        "bucket_pressure", "p_b", "MPa", 0.0, 40.0, 0.10, "hydraulic pressure at the bucket joint"
    ),
    Sensor(
        "pump_angle",
        "a",
        "rad",
        -0.35,
        0.35,
        0.002,
        "HST pump (swash-plate) angle, proportional to driving speed",
    ),
)

SENSOR_NAMES: tuple[str, ...] = tuple(s.name for s in SENSORS)
CONTROL_NAMES: tuple[str, ...] = ("boom", "bucket", "throttle")  # u_theta1, u_theta2, u_g
