"""Unit labels as loggers write them, and the conversion to pilerl's units.

A reading in ``source`` converts to ``target`` as ``value = raw * factor + offset``
(``conversion``). Units of one quantity convert into each other; anything else is an
error naming both. Labels are matched after trimming brackets and spaces
(``[bar]``, ``(deg)``), with common spellings as aliases (``°``, ``degree``, ``1/min``).
"""

from __future__ import annotations

import math

# quantity -> unit -> (factor to the quantity's base unit, offset in the base unit)
UNITS: dict[str, dict[str, tuple[float, float]]] = {
    "angle": {"rad": (1.0, 0.0), "mrad": (1e-3, 0.0), "deg": (math.pi / 180.0, 0.0)},
    "pressure": {
        "MPa": (1.0, 0.0),
        "kPa": (1e-3, 0.0),
        "Pa": (1e-6, 0.0),
        "bar": (0.1, 0.0),
        "mbar": (1e-4, 0.0),
        "psi": (6.894757293168361e-3, 0.0),
    },
    "time": {
        "s": (1.0, 0.0),
        "ms": (1e-3, 0.0),
        "us": (1e-6, 0.0),
        "ns": (1e-9, 0.0),
        "min": (60.0, 0.0),
        "h": (3600.0, 0.0),
    },
    "length": {"m": (1.0, 0.0), "cm": (1e-2, 0.0), "mm": (1e-3, 0.0)},
    "speed": {"m/s": (1.0, 0.0), "km/h": (1.0 / 3.6, 0.0)},
    "angular_speed": {
        "rad/s": (1.0, 0.0),
        "deg/s": (math.pi / 180.0, 0.0),
        "rpm": (2.0 * math.pi / 60.0, 0.0),
    },
    "force": {"N": (1.0, 0.0), "kN": (1e3, 0.0)},
    "mass": {"kg": (1.0, 0.0), "t": (1e3, 0.0)},
    "temperature": {"K": (1.0, 0.0), "degC": (1.0, 273.15)},
    # controls and other ratios: 1 = full scale
    "ratio": {"1": (1.0, 0.0), "%": (0.01, 0.0), "permille": (1e-3, 0.0)},
}
ALIASES = {
    "°": "deg",
    "degree": "deg",
    "degrees": "deg",
    "grad": "deg",
    "radian": "rad",
    "radians": "rad",
    "sec": "s",
    "second": "s",
    "seconds": "s",
    "msec": "ms",
    "µs": "us",
    "μs": "us",
    "1/min": "rpm",
    "u/min": "rpm",
    "°/s": "deg/s",
    "°c": "degC",
    "degc": "degC",
    "c": "degC",
    "-": "1",
    "": "1",
    "norm": "1",
    "‰": "permille",
    "percent": "%",
}
RAW = "raw"  # a declared source unit that means: no unit conversion, only scale/offset


class UnitError(ValueError):
    """An unknown unit label, or two units of different quantities."""


def normalise(label: str) -> str:
    """The table's spelling of a unit label (brackets, spaces and aliases resolved)."""
    text = label.strip().strip("[]()").strip()
    for units in UNITS.values():
        if text in units:
            return text
    lowered = text.lower()
    if lowered in ALIASES:
        return ALIASES[lowered]
    for units in UNITS.values():
        for name in units:
            if name.lower() == lowered:
                return name
    raise UnitError(f"unknown unit {label!r}; known units: {known_units()}")


def quantity(label: str) -> str:
    unit = normalise(label)
    return next(q for q, units in UNITS.items() if unit in units)


def conversion(source: str, target: str) -> tuple[float, float]:
    """``(factor, offset)`` with ``value[target] = raw[source] * factor + offset``."""
    src, dst = normalise(source), normalise(target)
    q_src, q_dst = quantity(src), quantity(dst)
    if q_src != q_dst:
        raise UnitError(f"cannot convert {source!r} ({q_src}) to {target!r} ({q_dst})")
    (f_src, o_src), (f_dst, o_dst) = UNITS[q_src][src], UNITS[q_dst][dst]
    return f_src / f_dst, (o_src - o_dst) / f_dst


def known_units() -> list[str]:
    return [u for units in UNITS.values() for u in units]
