"""Message logs (MCAP, ROS bags, CAN, MDF): signals that arrive at their own times.

A reader of such a format collects each signal as ``Signal(times_s, values, unit)``;
``sample_onto_grid`` then picks the mapped ones and samples them onto one grid at
``mapping.time.rate_hz`` by holding each signal's last value (what a controller running
at that rate would have seen). The grid starts when every mapped signal has a value and
ends at the last message of the signal that ends first. The longest interval between two
messages of each signal is kept for the quality report: holding a value hides a dropout.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import LogImportError
from ..mapping import ColumnRequest, LogMapping
from .base import LogTable, check_rows, resolve_columns

TIME_TOLERANCE_S = 1e-6  # a message this close after a grid time counts at it (float rounding)


@dataclass
class Signal:
    """One signal of a message log: sample times [s], values, the unit the log declares."""

    times_s: np.ndarray
    values: np.ndarray
    unit: str | None = None


class SignalCollector:
    """Gathers (time, value) samples per signal name while a reader walks its messages."""

    def __init__(self) -> None:
        self._times: dict[str, list[float]] = {}
        self._values: dict[str, list[float]] = {}
        self.units: dict[str, str] = {}

    def add(self, name: str, time_s: float, value: float, unit: str | None = None) -> None:
        self._times.setdefault(name, []).append(time_s)
        self._values.setdefault(name, []).append(value)
        if unit:
            self.units[name] = unit

    def add_fields(self, prefix: str, time_s: float, message: object) -> None:
        """Every numeric or boolean field of a (nested) message, named ``prefix.field``."""
        for name, value in _flatten(message, prefix):
            self.add(name, time_s, value)

    def signals(self) -> dict[str, Signal]:
        return {
            name: Signal(
                np.asarray(times, dtype=np.float64),
                np.asarray(self._values[name]),
                self.units.get(name),
            )
            for name, times in self._times.items()
        }


def _flatten(message: object, prefix: str):
    if isinstance(message, bool | int | float | np.integer | np.floating | np.bool_):
        yield prefix, float(message)
        return
    if isinstance(message, Mapping):
        items = message.items()
    elif hasattr(message, "__dataclass_fields__"):
        items = ((k, getattr(message, k)) for k in message.__dataclass_fields__)
    elif hasattr(message, "__slots__"):
        items = ((k, getattr(message, k)) for k in message.__slots__ if not k.startswith("_"))
    else:
        return  # text, arrays and other values are not signals
    for key, value in items:
        yield from _flatten(value, f"{prefix}.{key}" if prefix else str(key))


def sample_onto_grid(
    path: Path,
    signals: Mapping[str, Signal],
    requests: Sequence[ColumnRequest],
    mapping: LogMapping,
    *,
    kind: str,
) -> LogTable:
    """The mapped signals held onto a grid at ``mapping.time.rate_hz`` (see module doc)."""
    rate_hz = mapping.time.rate_hz
    if rate_hz is None:
        raise LogImportError(
            path,
            f"{kind} signals arrive at their own times: set time.rate_hz in the mapping "
            "(the rate they are sampled at)",
        )
    if mapping.time.column is not None:
        raise LogImportError(
            path,
            f"{kind} logs carry their own timestamps: leave time.column out of the mapping "
            "and give time.rate_hz",
        )
    if not signals:
        raise LogImportError(path, f"empty file (no {kind} messages with numeric fields)")
    names = resolve_columns(path, requests, sorted(signals))
    chosen = {name: signals[column] for name, column in names.items()}
    for name, signal in chosen.items():
        order = np.argsort(signal.times_s, kind="stable")
        signal.times_s, signal.values = signal.times_s[order], signal.values[order]
        if not np.isfinite(signal.times_s).all():
            raise LogImportError(path, "non-finite message time", column=names[name])
    origin = min(float(s.times_s[0]) for s in chosen.values())
    for signal in chosen.values():  # seconds since the first message: no 1e9-s offsets
        signal.times_s = signal.times_s - origin
    start = max(float(s.times_s[0]) for s in chosen.values())
    stop = min(float(s.times_s[-1]) for s in chosen.values())
    if stop < start:
        raise LogImportError(
            path, f"the mapped {kind} signals never overlap in time: no sample has all of them"
        )
    n = int(np.floor((stop - start + TIME_TOLERANCE_S) * rate_hz)) + 1
    check_rows(path, n)
    grid = start + np.arange(n) / rate_hz
    frame = {}
    for name, signal in chosen.items():
        last = np.searchsorted(signal.times_s, grid + TIME_TOLERANCE_S, side="right") - 1
        frame[name] = signal.values[last]
    table = LogTable(
        path,
        pd.DataFrame(frame),
        names,
        units={n: s.unit for n, s in chosen.items() if s.unit},
    )
    table.notes.append(
        f"{kind} signals sampled at {rate_hz:g} Hz by holding the last message "
        f"({n} rows from t = {start:.3f} s)"
    )
    table.signal_gaps = {
        name: float(np.diff(s.times_s).max()) if len(s.times_s) > 1 else 0.0
        for name, s in chosen.items()
    }
    return table
