"""Converting and checking the columns of a ``LogTable``: numbers, units, ranges, flags.

Every check reports the first bad row of the column it checks (1-based data rows).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from . import units as unit_table
from .mapping import ControlSpec, SensorSpec
from .readers import LogTable

CONTROL_TOLERANCE = 1e-6  # |u| up to 1 + this is accepted (float rounding) and clipped
TRUE_WORDS = frozenset({"true", "t", "yes", "y", "1", "1.0"})
FALSE_WORDS = frozenset({"false", "f", "no", "n", "0", "0.0"})


def numeric(table: LogTable, column: str) -> tuple[np.ndarray, np.ndarray]:
    """float64 values (NaN where empty or not a number) and the mask of non-numeric cells."""
    series = table.frame[column]
    if pd.api.types.is_bool_dtype(series) or pd.api.types.is_numeric_dtype(series):
        try:
            values = series.to_numpy(dtype=np.float64, na_value=np.nan)
        except (TypeError, ValueError) as error:
            raise table.error(f"not numeric ({error})", column=column) from None
        return values, np.zeros(len(values), dtype=bool)
    cells = series.to_numpy(dtype=object)
    text = np.array(["" if c is None else str(c).strip() for c in cells], dtype=object)
    blank = (text == "") | series.isna().to_numpy()
    try:  # fast path: every cell a number (Python's float parsing is exact)
        values = np.where(blank, "nan", text).astype(np.float64)
        return values, np.zeros(len(values), dtype=bool)
    except ValueError:
        pass
    values = np.full(len(text), np.nan)
    nonnumeric = np.zeros(len(text), dtype=bool)
    for i, cell in enumerate(text):
        if blank[i]:
            continue
        try:
            values[i] = float(cell)
        except ValueError:
            nonnumeric[i] = True
    return values, nonnumeric


def reject_first(
    table: LogTable,
    column: str,
    values: np.ndarray,
    nonnumeric: np.ndarray,
    out_of_range: np.ndarray,
    describe_range,
) -> None:
    """Raise for the first row that is non-numeric, non-finite or out of range."""
    bad = nonnumeric | ~np.isfinite(values) | out_of_range
    if not bad.any():
        return
    i = int(np.argmax(bad))
    if nonnumeric[i]:
        problem = f"non-numeric value {table.frame[column].iloc[i]!r}"
        if i == 0 and _is_unit(table.frame[column].iloc[i]):
            problem += " (a units row? set csv.units_row: true in the mapping)"
    elif np.isnan(values[i]):
        problem = "missing value (empty or NaN)"
    elif not np.isfinite(values[i]):
        problem = f"non-finite value {values[i]}"
    else:
        problem = describe_range(i)
    raise table.error(problem, column=column, row=i + 1)


def _is_unit(cell: object) -> bool:
    try:
        unit_table.normalise(str(cell))
    except unit_table.UnitError:
        return False
    return True


def unit_conversion(
    table: LogTable, column: str, declared: str | None, target: str, scale: float = 1.0
) -> tuple[float, float, str | None]:
    """``(factor, offset, source unit)`` from the raw unit to ``target``.

    The raw unit is the mapping's ``source_unit`` or else the one the file declares;
    both given and different is an error (one of them is wrong), as is a unit that does
    not convert to ``target``. ``raw`` and no unit at all mean no conversion. A unit
    from the file together with a ``scale`` but no ``source_unit`` is an error too: both
    would convert (a mapping written before the file had units would convert twice).
    """
    from_file = table.units.get(column)
    if declared == unit_table.RAW:
        return 1.0, 0.0, None
    if declared is None and from_file is not None and scale != 1.0:
        raise table.error(
            f"the file gives the unit {from_file!r} and the mapping a scale {scale:g}: both "
            f"would convert; drop the scale, or set source_unit: {from_file} (the scale is "
            "then a calibration after the conversion) or source_unit: raw (scale only)",
            column=column,
        )
    if declared is not None and from_file is not None:
        try:
            same = unit_table.normalise(declared) == unit_table.normalise(from_file)
        except unit_table.UnitError:
            same = False
        if not same:
            raise table.error(
                f"the mapping's source_unit {declared!r} and the file's unit {from_file!r} "
                "disagree; fix one (or set source_unit: raw to ignore the file's unit)",
                column=column,
            )
    source = declared or from_file
    if source is None:
        return 1.0, 0.0, None
    try:
        factor, offset = unit_table.conversion(source, target)
    except unit_table.UnitError as error:
        where = "mapping" if declared else "file's unit"
        raise table.error(
            f"{error} ({where}); set source_unit: raw and a scale if the column is "
            "in another quantity",
            column=column,
        ) from None
    return factor, offset, source


def sensor_values(table: LogTable, name: str, spec: SensorSpec) -> np.ndarray:
    """Converted readings [spec.unit], checked finite and within the mapping's range."""
    raw, nonnumeric = numeric(table, spec.column)
    factor, unit_offset, source = unit_conversion(
        table, spec.column, spec.source_unit, spec.unit, spec.scale
    )
    with np.errstate(invalid="ignore", over="ignore"):
        value = spec.convert(raw * factor + unit_offset)
    low, high = spec.range
    outside = (value < low) | (value > high)
    raw_unit = f" {source}" if source else ""

    def describe(i: int) -> str:
        return (
            f"{name} = {value[i]:.6g} {spec.unit} (raw {raw[i]:.6g}{raw_unit}) is outside the "
            f"physical range [{low:g}, {high:g}] {spec.unit}"
        )

    reject_first(table, spec.column, value, nonnumeric, outside, describe)
    return value


def control_values(table: LogTable, name: str, spec: ControlSpec) -> np.ndarray:
    """Normalised control, checked finite and within [-1, 1] (then clipped to it)."""
    raw, nonnumeric = numeric(table, spec.column)
    factor, unit_offset, source = unit_conversion(
        table, spec.column, spec.source_unit, "1", spec.scale
    )
    with np.errstate(invalid="ignore", over="ignore"):
        value = spec.convert(raw * factor + unit_offset)
    outside = np.abs(value) > 1.0 + CONTROL_TOLERANCE

    def describe(i: int) -> str:
        unit = f" {source}" if source else ""
        return (
            f"control {name} = {value[i]:.6g} (raw {raw[i]:.6g}{unit} * {spec.scale:g} + "
            f"{spec.offset:g}) is outside [-1, 1]"
        )

    reject_first(table, spec.column, value, nonnumeric, outside, describe)
    return np.clip(value, -1.0, 1.0)


def fill_fractions(table: LogTable, column: str) -> np.ndarray:
    raw, nonnumeric = numeric(table, column)
    negative_or_inf = np.isinf(raw) | (raw < 0)
    bad = nonnumeric | negative_or_inf
    if bad.any():
        i = int(np.argmax(bad))
        problem = (
            f"non-numeric value {table.frame[column].iloc[i]!r}"
            if nonnumeric[i]
            else f"fill fraction must be >= 0 and finite (or empty), got {raw[i]}"
        )
        raise table.error(problem, column=column, row=i + 1)
    return raw


def successes(table: LogTable, column: str) -> list[bool | None]:
    out: list[bool | None] = []
    for i, value in enumerate(table.frame[column].tolist()):
        if value is None or (isinstance(value, float) and math.isnan(value)):
            out.append(None)
            continue
        word = str(value).strip().lower()
        if isinstance(value, bool | np.bool_):
            out.append(bool(value))
        elif word in TRUE_WORDS or word in FALSE_WORDS:
            out.append(word in TRUE_WORDS)
        elif word in ("", "nan"):
            out.append(None)
        else:
            raise table.error(
                f"expected true/false, 1/0 or yes/no, got {value!r}", column=column, row=i + 1
            )
    return out


def label(value: object) -> str:
    """An episode id as text (``3.0`` -> ``3``)."""
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value).strip()
