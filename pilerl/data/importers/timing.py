"""The time base of a log: parsing (numbers in any unit, ISO timestamps), strict order,
sampling statistics (rate, jitter, gaps) and, on request, resampling onto a fixed rate."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from . import units as unit_table
from .columns import numeric, reject_first
from .mapping import LogMapping, TimeSpec
from .readers import LogTable

GAP_FACTOR = 1.5  # an interval longer than this many nominal periods is a gap


@dataclass
class Sampling:
    """How one episode was sampled, before any resampling.

    Attributes:
        n_rows: rows as logged.
        nominal_dt_s: the nominal interval (1 / declared rate, else the median) [s].
        median_dt_s: median interval [s].
        jitter_s: standard deviation of the intervals that are not gaps [s].
        gaps: ``(row, interval_s)`` per gap: 1-based data row after the gap, its length.
        dropped: samples missing in the gaps (interval / nominal - 1, rounded, summed).
        resampled_hz: the rate the episode was resampled to, or None.
    """

    n_rows: int
    nominal_dt_s: float
    median_dt_s: float
    jitter_s: float
    gaps: list[tuple[int, float]] = field(default_factory=list)
    dropped: int = 0
    resampled_hz: float | None = None


def parse_times(table: LogTable, spec: TimeSpec) -> np.ndarray:
    """Absolute time [s] of every row (numbers in the declared / file unit, or ISO)."""
    column = spec.column
    assert column is not None
    series = table.frame[column]
    if spec.format == "iso" or (spec.format == "auto" and _looks_like_date(series)):
        return _iso_times(table, column)
    raw, nonnumeric = numeric(table, column)
    seconds_per_unit = spec.scale
    unit = spec.unit or table.units.get(column)
    if unit is not None:
        try:
            factor, _ = unit_table.conversion(unit, "s")
        except unit_table.UnitError as error:
            raise table.error(f"time unit: {error}", column=column) from None
        if spec.unit is None and spec.scale != 1.0:
            raise table.error(
                f"the file gives the time unit {unit!r} and the mapping a time.scale "
                f"{spec.scale:g}: both convert to seconds; drop time.scale",
                column=column,
            )
        seconds_per_unit = factor
    times = raw * seconds_per_unit
    no_range = np.zeros(len(times), dtype=bool)
    reject_first(table, column, times, nonnumeric, no_range, lambda i: "")
    return times


def _looks_like_date(series: pd.Series) -> bool:
    if pd.api.types.is_datetime64_any_dtype(series):
        return True
    if pd.api.types.is_numeric_dtype(series) or len(series) == 0:
        return False
    first = str(series.iloc[0]).strip()
    try:
        float(first)
        return False
    except ValueError:
        pass
    try:
        pd.Timestamp(first)
    except (ValueError, TypeError):
        return False
    return True


def _iso_times(table: LogTable, column: str) -> np.ndarray:
    series = table.frame[column]
    try:
        stamps = pd.to_datetime(series, format="ISO8601", utc=True, errors="coerce")
    except (ValueError, TypeError):
        stamps = pd.Series(pd.NaT, index=series.index)
    bad = stamps.isna().to_numpy()
    if bad.any():
        i = int(np.argmax(bad))
        raise table.error(
            f"not an ISO 8601 timestamp: {series.iloc[i]!r}", column=column, row=i + 1
        )
    # seconds since the first row, plus the first row's POSIX time (UTC); the resolution
    # of pandas' datetimes varies, so no integer unit is assumed
    since_first = (stamps - stamps.iloc[0]).dt.total_seconds().to_numpy(dtype=np.float64)
    return since_first + stamps.iloc[0].timestamp()


def check_increasing(
    table: LogTable,
    mapping: LogMapping,
    times: np.ndarray,
    segments: Sequence[tuple[str, int, int]],
) -> None:
    """Time must increase strictly within each episode; a gap over ``max_gap_s`` fails."""
    column = mapping.time.column
    for _, start, end in segments:
        steps = np.diff(times[start:end])
        if (steps <= 0).any():
            i = start + int(np.argmax(steps <= 0)) + 1
            kind = "repeats" if times[i] == times[i - 1] else "is before"
            raise table.error(
                f"time is not strictly increasing: {_show(table, column, i)} {kind} "
                f"{_show(table, column, i - 1)} at the row before",
                column=column,
                row=i + 1,
            )
        limit = mapping.time.max_gap_s
        if limit is not None and (steps > limit).any():
            i = start + int(np.argmax(steps > limit)) + 1
            raise table.error(
                f"gap of {steps[i - start - 1]:.6g} s before this row, longer than "
                f"time.max_gap_s = {limit:g} s (dropped samples)",
                column=column,
                row=i + 1,
            )


def _show(table: LogTable, column: str, i: int) -> str:
    value = table.frame[column].iloc[i]
    if isinstance(value, float | np.floating):
        return f"{value:.9g}"
    return str(value)


def sampling(times_s: np.ndarray, rate_hz: float | None, first_row: int) -> Sampling:
    """Rate, jitter and gaps of one episode's times [s]; rows reported 1-based in the file."""
    steps = np.diff(times_s)
    if len(steps) == 0:
        nominal = 1.0 / rate_hz if rate_hz else float("nan")
        return Sampling(len(times_s), nominal, nominal, 0.0)
    median = float(np.median(steps))
    nominal = 1.0 / rate_hz if rate_hz else median
    is_gap = steps > GAP_FACTOR * nominal
    regular = steps[~is_gap]
    jitter = float(np.std(regular)) if len(regular) > 1 else 0.0
    gaps = [(first_row + int(i) + 1, float(steps[i])) for i in np.flatnonzero(is_gap)]
    dropped = int(sum(max(round(dt / nominal) - 1, 1) for _, dt in gaps))
    return Sampling(len(times_s), nominal, median, jitter, gaps, dropped)


def resample(
    time_s: np.ndarray,
    sensors: dict[str, np.ndarray],
    actions: np.ndarray,
    rate_hz: float,
) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """One episode on a grid from its first time at ``rate_hz``: sensors interpolated
    linearly, actions held (the command in force at each grid time)."""
    n = int(np.floor((time_s[-1] - time_s[0]) * rate_hz + 1e-9)) + 1
    grid = time_s[0] + np.arange(n) / rate_hz
    new_sensors = {name: np.interp(grid, time_s, values) for name, values in sensors.items()}
    held = np.searchsorted(time_s, grid + 1e-12, side="right") - 1
    return grid, new_sensors, actions[held]
