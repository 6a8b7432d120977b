"""Logs as machines write them, for the importer tests: a synthetic scoop in raw units."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
from pilerl_pile_loader.sensors import CONTROL_NAMES, SENSORS

from pilerl.data.importers import load_mapping

# pilerl sensor -> (logger column, logger unit); controls in percent
RAW_COLUMNS = {
    "boom_angle": ("Boom angle", "deg"),
    "bucket_angle": ("Bucket angle", "deg"),
    "drive_pressure": ("p drive", "bar"),
    "telescope_pressure": ("p tele", "bar"),
    "boom_pressure": ("p boom", "bar"),
    "bucket_pressure": ("p bucket", "bar"),
    "pump_angle": ("Pump", "mrad"),
}
CONTROL_COLUMNS = {"boom": "Joy boom", "bucket": "Joy bucket", "throttle": "Pedal"}
# the machine's own ranges (wider than the simulator's: a real boom goes to -35 deg)
MACHINE_RANGES = {
    "boom_angle": [-0.7, 1.2],
    "bucket_angle": [-1.3, 1.6],
    "drive_pressure": [0, 45],
    "telescope_pressure": [0, 45],
    "boom_pressure": [0, 45],
    "bucket_pressure": [0, 45],
    "pump_angle": [-0.4, 0.4],
}
UNITS = {s.name: s.unit for s in SENSORS}


def scoop(n: int, rate_hz: float = 50.0, seed: int = 0) -> dict[str, np.ndarray]:
    """A smooth synthetic scoop in pilerl units: sensor name / control name -> values,
    plus ``time_s``."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate_hz
    phase = np.linspace(0.0, 1.0, n)
    out = {
        "time_s": t,
        "boom_angle": -0.6 + 1.2 * phase**2 + rng.normal(0, 0.002, n),  # starts at -34 deg
        "bucket_angle": -0.3 + 1.4 * phase + rng.normal(0, 0.002, n),
        "drive_pressure": 12 + 20 * np.sin(math.pi * phase) + rng.normal(0, 0.1, n),
        "telescope_pressure": 8 + 6 * phase + rng.normal(0, 0.1, n),
        "boom_pressure": 10 + 15 * phase + rng.normal(0, 0.1, n),
        "bucket_pressure": 9 + 10 * np.sin(math.pi * phase) + rng.normal(0, 0.1, n),
        "pump_angle": 0.2 * np.sin(2 * math.pi * phase) + rng.normal(0, 0.001, n),
        "boom": np.where(phase > 0.5, 0.8, 0.0),
        "bucket": np.where(phase < 0.5, 0.6, 0.0),
        "throttle": np.full(n, 0.7),
    }
    return out


def to_raw(values: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Logger column -> raw values: time in ms, angles in deg, pressures in bar, % commands."""
    raw = {"Time": np.round(values["time_s"] * 1000.0, 3)}
    factor = {"deg": 180 / math.pi, "bar": 10.0, "mrad": 1000.0}
    for name, (column, unit) in RAW_COLUMNS.items():
        raw[column] = values[name] * factor[unit]
    for name, column in CONTROL_COLUMNS.items():
        raw[column] = values[name] * 100.0
    return raw


def write_logger_csv(
    path: Path,
    values: dict[str, np.ndarray],
    *,
    separator: str = ";",
    decimal: str = ",",
    units_row: bool = True,
    comments: bool = True,
    extra_column: bool = True,
) -> Path:
    """A CSV as a European data logger writes it: preamble comments, ``;`` separator,
    decimal commas, a units row, a trailing unmapped column."""
    raw = to_raw(values)
    if extra_column:
        raw["Engine temp"] = np.full(len(raw["Time"]), 81.5)
    units = (
        ["ms"]
        + [u for _, u in RAW_COLUMNS.values()]
        + ["%"] * 3
        + (["degC"] if extra_column else [])
    )
    lines = []
    if comments:
        lines += ["# Logger XL-200 export", "# machine: WL-7, site A"]
    lines.append(separator.join(raw))
    if units_row:
        lines.append(separator.join(units))
    columns = list(raw.values())
    for i in range(len(columns[0])):
        cells = [f"{c[i]:.6f}".replace(".", decimal) for c in columns]
        lines.append(separator.join(cells))
    path.write_text("\n".join(lines) + "\n")
    return path


def logger_mapping_dict(**time) -> dict:
    """The mapping of ``write_logger_csv`` logs: units come from the units row."""
    return {
        "sensors": {
            name: {"column": column, "unit": UNITS[name], "range": MACHINE_RANGES[name]}
            for name, (column, _) in RAW_COLUMNS.items()
        },
        "controls": {name: {"column": column} for name, column in CONTROL_COLUMNS.items()},
        "time": {"column": "Time", **time},
        "csv": {"units_row": True},
        "metadata": {"condition": "site-a", "operator_id": "op1", "success": True},
    }


def logger_mapping(**time):
    return load_mapping(logger_mapping_dict(**time))


def sensor_names() -> list[str]:
    return [s.name for s in SENSORS]


def control_names() -> list[str]:
    return list(CONTROL_NAMES)


def frame_of(values: dict[str, np.ndarray]) -> pd.DataFrame:
    return pd.DataFrame(to_raw(values))
