"""Import real machine logs (CSV, Parquet, HDF5) into schema-v1 episodes.

A ``LogMapping`` declares where each pilerl signal is in a log and how to convert it:

* every sensor: source column, unit label, ``value = raw * scale + offset`` and the
  physical range ``[low, high]`` (pilerl units) outside which a reading is rejected;
* every control: source column and ``u = raw * scale + offset``, which must land in
  [-1, 1];
* time: a column in any unit (``scale`` converts it to seconds), or a fixed ``rate_hz``
  when the log has no time column;
* an optional episode column that splits one file into several episodes (otherwise one
  file = one episode; rows of one episode must be contiguous);
* episode metadata: condition label, operator id, and fill fraction / success either as
  fixed values or as columns (the value at the episode's last row counts).

``import_logs(paths, mapping, store)`` reads every file (by extension: ``.csv``,
``.parquet``/``.pq``, ``.h5``/``.hdf5``; HDF5 holds one 1-D dataset per column in the
group ``mapping.hdf5_group``), validates *all* episodes of *all* files, and only then
appends them to the ``EpisodeStore``: a bad file leaves the store as it was.

Episode construction, per file (or per episode-column run):

* ``<sensor>`` at row i is the converted reading at row i, ``("next", <sensor>)`` the
  reading at row i + 1. The last row has no later reading, so its ``next`` repeats its own
  reading and the row is flagged ``done`` and ``terminated`` (the demonstration ended
  there: nothing to bootstrap beyond it), ``truncated`` stays False.
* ``time_s`` is the converted time minus the episode's first time (time since the
  episode start, s; ``time.start_at_zero: false`` keeps the log's times); ``rate_hz`` in
  the metadata is ``time.rate_hz`` when given, else 1 / median sample interval.
* rewards are NaN (unknown).

Every problem in a log is a ``LogImportError`` (a ``SchemaError``) whose message names
the file, the column and the row, rows counted as *1-based data rows* (the first row
after a CSV header is row 1; in Parquet/HDF5 row 1 is index 0). The message reports the
first bad row of the first bad column, columns checked in the order: episode, time,
sensors, controls, metadata columns. A malformed mapping is a ``MappingError``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import types
import typing
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import torch
import yaml
from tensordict import TensorDict

from pilerl.io import write_text_atomic

from .schema import EpisodeMeta, SchemaError, make_episode, validate_episode
from .store import EpisodeStore

ROWS = "1-based data row"
CSV_SUFFIXES = (".csv", ".csv.gz")
PARQUET_SUFFIXES = (".parquet", ".pq")
HDF5_SUFFIXES = (".h5", ".hdf5")
CONTROL_TOLERANCE = 1e-6  # |u| up to 1 + this is accepted (float rounding) and clipped
TRUE_WORDS = frozenset({"true", "t", "yes", "y", "1", "1.0"})
FALSE_WORDS = frozenset({"false", "f", "no", "n", "0", "0.0"})


# ---------------------------------------------------------------------------- errors
class MappingError(SchemaError):
    """A column mapping is malformed or does not fit the store; the message names the field."""


class LogImportError(SchemaError):
    """A log file cannot be imported; names the file, and the column and row where they apply.

    Attributes:
        file: the log file, as given.
        column: the source column, or None (unreadable / empty file).
        row: 1-based data row, or None (a whole-column or whole-file problem).
    """

    def __init__(
        self, file: str | Path, problem: str, *, column: str | None = None, row: int | None = None
    ) -> None:
        self.file, self.column, self.row, self.problem = str(file), column, row, problem
        where = []
        if column is not None:
            where.append(f"column {column!r}")
        if row is not None:
            where.append(f"row {row} ({ROWS})")
        prefix = f"{file}: " + (", ".join(where) + ": " if where else "")
        super().__init__(prefix + problem)

    def __reduce__(self):  # keep the exception picklable (multiprocessing, pytest-xdist)
        return _rebuild_error, (self.file, self.problem, self.column, self.row)


def _rebuild_error(file: str, problem: str, column: str | None, row: int | None):
    return LogImportError(file, problem, column=column, row=row)


# ---------------------------------------------------------------------------- mapping
@dataclass
class SensorSpec:
    """Where one sensor's reading is in a log and how to convert it.

    Attributes:
        column: source column name.
        unit: pilerl unit of the converted value (``rad``, ``MPa``...); must equal the
            store's unit for this sensor.
        range: physical range ``[low, high]`` in ``unit``; a converted reading outside it is
            rejected (``-.inf`` / ``.inf`` in YAML for an open end).
        scale: multiplier from the raw value to ``unit`` (e.g. 0.1 for bar -> MPa).
        offset: added after scaling, in ``unit``.
    """

    column: str
    unit: str
    range: list[float]
    scale: float = 1.0
    offset: float = 0.0

    def convert(self, raw: np.ndarray) -> np.ndarray:
        """Raw readings -> pilerl unit: ``raw * scale + offset``."""
        return raw * self.scale + self.offset


@dataclass
class ControlSpec:
    """Where one control is in a log; ``u = raw * scale + offset`` must lie in [-1, 1].

    Attributes:
        column: source column name.
        scale: multiplier from the raw command to the normalised control (e.g. 1/100 for %).
        offset: added after scaling.
    """

    column: str
    scale: float = 1.0
    offset: float = 0.0

    def convert(self, raw: np.ndarray) -> np.ndarray:
        """Raw commands -> normalised control: ``raw * scale + offset``."""
        return raw * self.scale + self.offset


@dataclass
class TimeSpec:
    """The time base of a log.

    Attributes:
        column: time column, any origin, or None when the log has no time column.
        scale: seconds per raw time unit (0.001 for milliseconds).
        rate_hz: sampling rate [Hz]; required without a time column (time = row / rate_hz),
            otherwise the nominal rate written to the metadata (default: 1 / median
            interval).
        start_at_zero: subtract the episode's first time, so that ``time_s`` is the time
            since the episode start (the schema's meaning); False keeps the log's times.
    """

    column: str | None = None
    scale: float = 1.0
    rate_hz: float | None = None
    start_at_zero: bool = True


@dataclass
class MetadataSpec:
    """Episode-level metadata of imported logs (``EpisodeMeta`` fields).

    Attributes:
        condition: condition label (``summer``, ``site-A-frozen``...).
        condition_params: known material / ground / hydraulics parameters.
        operator_id: who drove (free text); stored as ``operator = {"id", "kind"}``.
        operator_kind: ``human`` for real logs.
        fill_fraction: final bucket fill (fraction of rated capacity) for every episode.
        fill_fraction_column: column holding the fill fraction (value at the episode's
            last row; NaN = unknown). Exclusive with ``fill_fraction``.
        success: the half-full rule outcome for every episode.
        success_column: column holding the outcome (true/false, 1/0, yes/no; empty =
            unknown; value at the last row). Exclusive with ``success``.
    """

    condition: str = "unknown"
    condition_params: dict = field(default_factory=dict)
    operator_id: str = ""
    operator_kind: str = "human"
    fill_fraction: float | None = None
    fill_fraction_column: str | None = None
    success: bool | None = None
    success_column: str | None = None


@dataclass
class LogMapping:
    """How a machine log maps onto pilerl's episodes (see the module docstring).

    Attributes:
        sensors: pilerl sensor name -> ``SensorSpec``.
        controls: pilerl control name -> ``ControlSpec``.
        time: the time base.
        episode_column: column whose value changes between episodes; None = one file is
            one episode.
        hdf5_group: HDF5 group holding one dataset per column.
        csv_delimiter: CSV field separator.
        metadata: episode metadata.
    """

    sensors: dict[str, SensorSpec]
    controls: dict[str, ControlSpec]
    time: TimeSpec = field(default_factory=TimeSpec)
    episode_column: str | None = None
    hdf5_group: str = "/"
    csv_delimiter: str = ","
    metadata: MetadataSpec = field(default_factory=MetadataSpec)

    def columns(self) -> list[str]:
        """Every source column the mapping reads, once each, in checking order."""
        meta = self.metadata
        names = [
            self.episode_column,
            self.time.column,
            *(s.column for s in self.sensors.values()),
            *(c.column for c in self.controls.values()),
            meta.fill_fraction_column,
            meta.success_column,
        ]
        return list(dict.fromkeys(n for n in names if n is not None))


def load_mapping(source: LogMapping | Mapping | str | Path) -> LogMapping:
    """A checked ``LogMapping`` from a YAML file, a plain dict / DictConfig, or a mapping.

    Raises ``MappingError`` naming the field on unknown, missing or mistyped fields.
    """
    if isinstance(source, LogMapping):
        check_mapping(source)
        return source
    if isinstance(source, str | Path):
        path = Path(source)
        try:
            data = yaml.safe_load(path.read_text())
        except (OSError, yaml.YAMLError) as error:
            raise MappingError(f"{path}: cannot read the mapping ({error})") from None
        return mapping_from_dict(data, where=str(path))
    return mapping_from_dict(source)


def mapping_from_dict(data: Mapping, *, where: str = "mapping") -> LogMapping:
    """Build and check a ``LogMapping`` from plain data (YAML / JSON / DictConfig)."""
    from omegaconf import DictConfig, OmegaConf

    if isinstance(data, DictConfig):
        data = OmegaConf.to_container(data, resolve=True)
    mapping = _from_dict(LogMapping, data, where)
    check_mapping(mapping, where=where)
    return mapping


def mapping_to_dict(mapping: LogMapping) -> dict:
    """Plain data for YAML / JSON (``mapping_from_dict`` reads it back)."""
    return dataclasses.asdict(mapping)


def save_mapping(mapping: LogMapping, path: str | Path) -> Path:
    """Write ``mapping`` as YAML (atomically); returns the path."""
    path = Path(path)
    write_text_atomic(path, yaml.safe_dump(mapping_to_dict(mapping), sort_keys=False))
    return path


def check_mapping(mapping: LogMapping, *, where: str = "mapping") -> None:
    """Raise ``MappingError`` naming the field if a value makes no sense."""
    if not mapping.sensors:
        raise MappingError(f"{where}.sensors: at least one sensor is needed")
    for name, sensor in mapping.sensors.items():
        path = f"{where}.sensors.{name}"
        _check_column_name(sensor.column, f"{path}.column")
        _check_scale(sensor.scale, sensor.offset, path)
        if len(sensor.range) != 2 or not sensor.range[0] < sensor.range[1]:
            raise MappingError(
                f"{path}.range: expected [low, high] with low < high, got {sensor.range}"
            )
    for name, control in mapping.controls.items():
        path = f"{where}.controls.{name}"
        _check_column_name(control.column, f"{path}.column")
        _check_scale(control.scale, control.offset, path)
    _check_time(mapping.time, f"{where}.time")
    if mapping.episode_column is not None:
        _check_column_name(mapping.episode_column, f"{where}.episode_column")
    if not mapping.csv_delimiter:
        raise MappingError(f"{where}.csv_delimiter: must not be empty")
    _check_metadata(mapping.metadata, f"{where}.metadata")


def check_against_store(mapping: LogMapping, store: EpisodeStore) -> None:
    """Raise ``MappingError`` unless the mapping has exactly the store's sensors (same
    units) and controls."""
    _check_names("sensors", mapping.sensors, store.sensors)
    _check_names("controls", mapping.controls, store.controls)
    for name, unit in store.sensors.items():
        if mapping.sensors[name].unit != unit:
            raise MappingError(
                f"mapping.sensors.{name}.unit: {mapping.sensors[name].unit!r}, "
                f"the dataset {store.root} records {name} in {unit!r}"
            )


def _check_names(kind: str, declared: Mapping, expected: Iterable[str]) -> None:
    expected = list(expected)
    missing = [n for n in expected if n not in declared]
    extra = [n for n in declared if n not in expected]
    if missing or extra:
        raise MappingError(
            f"mapping.{kind}: the dataset has {expected}; "
            f"missing {missing}, not in the dataset {extra}"
        )


def _check_column_name(column: str, path: str) -> None:
    if not column:
        raise MappingError(f"{path}: empty column name")


def _check_scale(scale: float, offset: float, path: str) -> None:
    if not math.isfinite(scale) or scale == 0.0:
        raise MappingError(f"{path}.scale: must be finite and non-zero, got {scale}")
    if not math.isfinite(offset):
        raise MappingError(f"{path}.offset: must be finite, got {offset}")


def _check_time(time: TimeSpec, path: str) -> None:
    if time.column is None and time.rate_hz is None:
        raise MappingError(f"{path}: give a time column or rate_hz")
    if time.column is not None:
        _check_column_name(time.column, f"{path}.column")
    if not (math.isfinite(time.scale) and time.scale > 0):
        raise MappingError(f"{path}.scale: seconds per raw unit must be > 0, got {time.scale}")
    if time.rate_hz is not None and not (math.isfinite(time.rate_hz) and time.rate_hz > 0):
        raise MappingError(f"{path}.rate_hz: must be > 0 Hz, got {time.rate_hz}")


def _check_metadata(meta: MetadataSpec, path: str) -> None:
    if meta.fill_fraction is not None and meta.fill_fraction_column is not None:
        raise MappingError(f"{path}: give fill_fraction or fill_fraction_column, not both")
    if meta.success is not None and meta.success_column is not None:
        raise MappingError(f"{path}: give success or success_column, not both")
    if meta.fill_fraction is not None and not (
        math.isfinite(meta.fill_fraction) and meta.fill_fraction >= 0
    ):
        raise MappingError(f"{path}.fill_fraction: must be >= 0, got {meta.fill_fraction}")


# -- typed construction from plain data -----------------------------------------------
def _from_dict(cls: type, data: object, path: str):
    if not isinstance(data, Mapping):
        raise MappingError(f"{path}: expected a mapping of fields, got {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(str(k) for k in data if k not in fields)
    if unknown:
        raise MappingError(f"{path}: unknown field(s) {unknown}; known fields: {list(fields)}")
    missing = [
        name
        for name, f in fields.items()
        if name not in data
        and f.default is dataclasses.MISSING
        and f.default_factory is dataclasses.MISSING
    ]
    if missing:
        raise MappingError(f"{path}: missing required field(s) {missing}")
    return cls(**{k: _convert(v, hints[k], f"{path}.{k}") for k, v in data.items()})


def _convert(value: object, annotation: object, path: str):
    if dataclasses.is_dataclass(annotation):
        return _from_dict(annotation, value, path)
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin in (types.UnionType, typing.Union):
        if value is None and type(None) in args:
            return None
        (inner,) = [a for a in args if a is not type(None)]
        return _convert(value, inner, path)
    if origin is list:
        if not isinstance(value, list | tuple):
            raise MappingError(f"{path}: expected a list, got {value!r}")
        return [_convert(v, args[0], f"{path}[{i}]") for i, v in enumerate(value)]
    if origin is dict or annotation is dict:
        if not isinstance(value, Mapping):
            raise MappingError(f"{path}: expected a mapping, got {value!r}")
        if not args:
            return dict(value)
        return {
            _convert(k, args[0], path): _convert(v, args[1], f"{path}.{k}")
            for k, v in value.items()
        }
    return _convert_scalar(value, annotation, path)


def _convert_scalar(value: object, annotation: object, path: str):
    if annotation is float and isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    if annotation is bool and isinstance(value, bool):
        return value
    if annotation is str and isinstance(value, str):
        return value
    if annotation is str and isinstance(value, int) and not isinstance(value, bool):
        return str(value)  # a numeric column header or operator id written unquoted in YAML
    name = getattr(annotation, "__name__", str(annotation))
    raise MappingError(f"{path}: expected {name}, got {value!r}")


# ---------------------------------------------------------------------------- reading
def read_log(
    path: str | Path, columns: Sequence[str], *, hdf5_group: str = "/", csv_delimiter: str = ","
) -> pd.DataFrame:
    """The named columns of one log file, as read (no conversion); format by extension.

    Raises ``LogImportError`` for a missing, empty, corrupt or unreadable file, a missing
    column, or (HDF5) a column that is not 1-D or shorter/longer than the others.
    """
    path = Path(path)
    if not path.is_file():
        raise LogImportError(path, "no such file")
    if path.stat().st_size == 0:
        raise LogImportError(path, "empty file (0 bytes)")
    name = path.name.lower()
    if name.endswith(CSV_SUFFIXES):
        table = _read_csv(path, columns, csv_delimiter)
    elif name.endswith(PARQUET_SUFFIXES):
        table = _read_parquet(path, columns)
    elif name.endswith(HDF5_SUFFIXES):
        table = _read_hdf5(path, columns, hdf5_group)
    else:
        known = CSV_SUFFIXES + PARQUET_SUFFIXES + HDF5_SUFFIXES
        raise LogImportError(path, f"unknown log format; expected one of {list(known)}")
    if len(table) == 0:
        raise LogImportError(path, "empty file (no data rows)")
    return table


def _missing(path: Path, columns: Sequence[str], available: Sequence[str]) -> None:
    missing = [c for c in columns if c not in available]
    if missing:
        raise LogImportError(
            path, f"missing column (the file has {list(available)})", column=missing[0]
        )


def _read_csv(path: Path, columns: Sequence[str], delimiter: str) -> pd.DataFrame:
    """All columns are parsed (not only the mapped ones), so that a row with more fields
    than the header is an error rather than silently shifted; short rows read as missing."""
    try:
        table = pd.read_csv(path, sep=delimiter, low_memory=False)
    except pd.errors.EmptyDataError:
        raise LogImportError(path, "empty file (no header)") from None
    except (pd.errors.ParserError, UnicodeDecodeError, OSError, ValueError) as error:
        raise LogImportError(path, f"unreadable CSV ({_first_line(error)})") from None
    _missing(path, columns, list(table.columns))
    return table[list(columns)]


def _read_parquet(path: Path, columns: Sequence[str]) -> pd.DataFrame:
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        _missing(path, columns, pq.read_schema(path).names)
        return pq.read_table(path, columns=list(columns)).to_pandas()
    except LogImportError:
        raise
    except (pa.ArrowException, OSError, ValueError) as error:
        raise LogImportError(path, f"unreadable Parquet ({_first_line(error)})") from None


def _read_hdf5(path: Path, columns: Sequence[str], group_name: str) -> pd.DataFrame:
    import h5py

    try:
        with h5py.File(path, "r") as h5:
            group = h5.get(group_name)
            if not isinstance(group, h5py.Group):
                raise LogImportError(path, f"no HDF5 group {group_name!r}")
            available = [k for k, v in group.items() if isinstance(v, h5py.Dataset)]
            _missing(path, columns, available)
            data = {c: _hdf5_column(path, c, group[c]) for c in columns}
    except LogImportError:
        raise
    except (OSError, KeyError, ValueError, TypeError) as error:
        raise LogImportError(path, f"unreadable HDF5 ({_first_line(error)})") from None
    n_rows = max(len(v) for v in data.values())
    for column, values in data.items():
        if len(values) != n_rows:
            raise LogImportError(
                path,
                f"no value: the column has {len(values)} rows, others have up to {n_rows}",
                column=column,
                row=len(values) + 1,
            )
    return pd.DataFrame(data)


def _hdf5_column(path: Path, column: str, dataset) -> np.ndarray:
    values = dataset[()]
    if values.ndim == 2 and values.shape[1] == 1:
        values = values[:, 0]
    if values.ndim != 1:
        raise LogImportError(
            path, f"expected a 1-D dataset, got shape {values.shape}", column=column
        )
    if values.dtype.kind == "S":
        values = np.array([v.decode("utf-8", "replace") for v in values], dtype=object)
    elif values.dtype.kind == "O":
        values = np.array(
            [v.decode("utf-8", "replace") if isinstance(v, bytes) else v for v in values],
            dtype=object,
        )
    return values


def _first_line(error: BaseException) -> str:
    text = str(error).strip().splitlines()
    return f"{type(error).__name__}: {text[0] if text else ''}"


# ---------------------------------------------------------------------------- checking
def _numeric(path: Path, table: pd.DataFrame, column: str) -> tuple[np.ndarray, np.ndarray]:
    """float64 values (NaN where empty or not a number) and the mask of non-numeric cells."""
    series = table[column]
    if pd.api.types.is_bool_dtype(series) or pd.api.types.is_numeric_dtype(series):
        try:
            values = series.to_numpy(dtype=np.float64, na_value=np.nan)
        except (TypeError, ValueError) as error:
            raise LogImportError(path, f"not numeric ({error})", column=column) from None
        return values, np.zeros(len(values), dtype=bool)
    values = pd.to_numeric(series, errors="coerce").to_numpy(dtype=np.float64, na_value=np.nan)
    blank = series.isna().to_numpy() | series.astype(str).str.strip().eq("").to_numpy()
    return values, np.isnan(values) & ~blank


def _reject_first(
    path: Path,
    table: pd.DataFrame,
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
        problem = f"non-numeric value {table[column].iloc[i]!r}"
    elif np.isnan(values[i]):
        problem = "missing value (empty or NaN)"
    elif not np.isfinite(values[i]):
        problem = f"non-finite value {values[i]}"
    else:
        problem = describe_range(i)
    raise LogImportError(path, problem, column=column, row=i + 1)


def _sensor(path: Path, table: pd.DataFrame, name: str, spec: SensorSpec) -> np.ndarray:
    """Converted readings [spec.unit], checked finite and within the physical range."""
    raw, nonnumeric = _numeric(path, table, spec.column)
    with np.errstate(invalid="ignore", over="ignore"):
        value = spec.convert(raw)
    low, high = spec.range
    outside = (value < low) | (value > high)

    def describe(i: int) -> str:
        return (
            f"{name} = {value[i]:.6g} {spec.unit} (raw {raw[i]:.6g}) is outside the "
            f"physical range [{low:g}, {high:g}] {spec.unit}"
        )

    _reject_first(path, table, spec.column, value, nonnumeric, outside, describe)
    return value


def _control(path: Path, table: pd.DataFrame, name: str, spec: ControlSpec) -> np.ndarray:
    """Normalised control, checked finite and within [-1, 1] (then clipped to it)."""
    raw, nonnumeric = _numeric(path, table, spec.column)
    with np.errstate(invalid="ignore", over="ignore"):
        value = spec.convert(raw)
    outside = np.abs(value) > 1.0 + CONTROL_TOLERANCE

    def describe(i: int) -> str:
        return (
            f"control {name} = {value[i]:.6g} (raw {raw[i]:.6g} * {spec.scale:g} + "
            f"{spec.offset:g}) is outside [-1, 1]"
        )

    _reject_first(path, table, spec.column, value, nonnumeric, outside, describe)
    return np.clip(value, -1.0, 1.0)


def _segments(path: Path, table: pd.DataFrame, column: str | None) -> list[tuple[str, int, int]]:
    """(episode label, first row index, end row index) for each episode of a file."""
    n = len(table)
    if column is None:
        return [("", 0, n)]
    series = table[column]
    missing = series.isna().to_numpy()
    if missing.any():
        raise LogImportError(
            path, "missing episode id", column=column, row=int(np.argmax(missing)) + 1
        )
    labels = [_label(v) for v in series.tolist()]
    starts = [0] + [i for i in range(1, n) if labels[i] != labels[i - 1]]
    seen: set[str] = set()
    for start in starts:
        if labels[start] in seen:
            raise LogImportError(
                path,
                f"episode {labels[start]!r} appears again after other "
                "episodes; the rows of one episode must be contiguous",
                column=column,
                row=start + 1,
            )
        seen.add(labels[start])
    ends = [*starts[1:], n]
    return [(labels[s], s, e) for s, e in zip(starts, ends, strict=True)]


def _label(value: object) -> str:
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value).strip()


def _times(
    path: Path, table: pd.DataFrame, mapping: LogMapping, segments: Sequence[tuple[str, int, int]]
) -> np.ndarray:
    """Absolute time [s] of every row, strictly increasing within each episode."""
    spec = mapping.time
    if spec.column is None:
        times = np.empty(len(table))
        for _, start, end in segments:
            times[start:end] = np.arange(end - start) / spec.rate_hz
        return times
    raw, nonnumeric = _numeric(path, table, spec.column)
    times = raw * spec.scale
    no_range = np.zeros(len(times), dtype=bool)
    _reject_first(path, table, spec.column, times, nonnumeric, no_range, lambda i: "")
    for _, start, end in segments:
        steps = np.diff(times[start:end])
        if (steps <= 0).any():
            i = start + int(np.argmax(steps <= 0)) + 1
            kind = "repeats" if times[i] == times[i - 1] else "is before"
            raise LogImportError(
                path,
                f"time is not strictly increasing: {raw[i]:.9g} {kind} "
                f"{raw[i - 1]:.9g} at the row before",
                column=spec.column,
                row=i + 1,
            )
    return times


def _fill_fractions(path: Path, table: pd.DataFrame, column: str) -> np.ndarray:
    raw, nonnumeric = _numeric(path, table, column)
    negative_or_inf = np.isinf(raw) | (raw < 0)
    bad = nonnumeric | negative_or_inf
    if bad.any():
        i = int(np.argmax(bad))
        problem = (
            f"non-numeric value {table[column].iloc[i]!r}"
            if nonnumeric[i]
            else f"fill fraction must be >= 0 and finite (or empty), got {raw[i]}"
        )
        raise LogImportError(path, problem, column=column, row=i + 1)
    return raw


def _successes(path: Path, table: pd.DataFrame, column: str) -> list[bool | None]:
    out: list[bool | None] = []
    for i, value in enumerate(table[column].tolist()):
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
            raise LogImportError(
                path, f"expected true/false, 1/0 or yes/no, got {value!r}", column=column, row=i + 1
            )
    return out


def _fill_per_row(path: Path, table: pd.DataFrame, spec: MetadataSpec) -> np.ndarray:
    """Fill fraction at every row (NaN = unknown): the column, or the fixed value."""
    if spec.fill_fraction_column is not None:
        return _fill_fractions(path, table, spec.fill_fraction_column)
    value = math.nan if spec.fill_fraction is None else spec.fill_fraction
    return np.full(len(table), value)


def _success_per_row(path: Path, table: pd.DataFrame, spec: MetadataSpec) -> list[bool | None]:
    """Half-full outcome at every row (None = unknown): the column, or the fixed value."""
    if spec.success_column is not None:
        return _successes(path, table, spec.success_column)
    return [spec.success] * len(table)


# ---------------------------------------------------------------------------- episodes
def _episode(
    sensors: Mapping[str, np.ndarray], actions: np.ndarray, time_s: np.ndarray
) -> TensorDict:
    """A schema-v1 episode; ``next`` is the following row, the last row repeats itself."""
    current = {k: torch.from_numpy(v.astype(np.float32)) for k, v in sensors.items()}
    following = {k: torch.cat([v[1:], v[-1:]]) for k, v in current.items()}
    return make_episode(
        sensors=current,
        next_sensors=following,
        actions=torch.from_numpy(actions.astype(np.float32)),
        time_s=torch.from_numpy(np.ascontiguousarray(time_s, dtype=np.float64)),
        terminated=True,
    )


def _rate_hz(path: Path, mapping: LogMapping, time_s: np.ndarray, label: str) -> float:
    if mapping.time.rate_hz is not None:
        return float(mapping.time.rate_hz)
    if len(time_s) < 2:
        where = f" (episode {label!r})" if label else ""
        raise LogImportError(
            path,
            f"one row{where}: cannot estimate the sampling rate; set time.rate_hz in the mapping",
            column=mapping.time.column,
        )
    return float(f"{1.0 / float(np.median(np.diff(time_s))):.9g}")


def _meta(
    path: Path, mapping: LogMapping, label: str, rate_hz: float, fill: float, success: bool | None
) -> EpisodeMeta:
    spec = mapping.metadata
    return EpisodeMeta(
        rate_hz=rate_hz,
        source=f"import:{path}" + (f"#episode={label}" if label else ""),
        condition=spec.condition,
        condition_params=dict(spec.condition_params),
        operator={"id": spec.operator_id, "kind": spec.operator_kind},
        fill_fraction=fill,
        success=success,
    )


def read_episodes(
    path: str | Path,
    mapping: LogMapping,
    *,
    sensor_order: Sequence[str] | None = None,
    control_order: Sequence[str] | None = None,
) -> list[tuple[TensorDict, EpisodeMeta]]:
    """Read, check and convert one log file into episodes (nothing is written).

    Args:
        path: the log file.
        mapping: the column mapping.
        sensor_order: sensor keys of the result (default: the mapping's order).
        control_order: order of the action components (default: the mapping's order).
    """
    path = Path(path)
    sensor_order = list(sensor_order or mapping.sensors)
    control_order = list(control_order or mapping.controls)
    table = read_log(
        path, mapping.columns(), hdf5_group=mapping.hdf5_group, csv_delimiter=mapping.csv_delimiter
    )
    segments = _segments(path, table, mapping.episode_column)
    times = _times(path, table, mapping, segments)
    sensors = {n: _sensor(path, table, n, mapping.sensors[n]) for n in sensor_order}
    actions = (
        np.stack([_control(path, table, n, mapping.controls[n]) for n in control_order], axis=-1)
        if control_order
        else np.zeros((len(table), 0))
    )
    fills = _fill_per_row(path, table, mapping.metadata)
    successes = _success_per_row(path, table, mapping.metadata)
    episodes = []
    for label, start, end in segments:
        rows = slice(start, end)
        time_s = times[rows] - times[start] if mapping.time.start_at_zero else times[rows]
        td = _episode({n: v[rows] for n, v in sensors.items()}, actions[rows], time_s)
        validate_episode(
            td, sensor_order, action_dim=len(control_order), where=f"{path} episode {label or 0}"
        )
        fill, success = float(fills[end - 1]), successes[end - 1]  # value at the last row
        rate = _rate_hz(path, mapping, times[rows], label)
        episodes.append((td, _meta(path, mapping, label, rate, fill, success)))
    return episodes


def read_logs(
    paths: str | Path | Iterable[str | Path],
    mapping: LogMapping | Mapping | str | Path,
    *,
    sensor_order: Sequence[str] | None = None,
    control_order: Sequence[str] | None = None,
) -> list[tuple[TensorDict, EpisodeMeta]]:
    """``read_episodes`` over several files: every episode of every file, or the first error."""
    mapping = load_mapping(mapping)
    episodes = []
    for path in _as_paths(paths):
        episodes += read_episodes(
            path, mapping, sensor_order=sensor_order, control_order=control_order
        )
    return episodes


def import_logs(
    paths: str | Path | Iterable[str | Path],
    mapping: LogMapping | Mapping | str | Path,
    store: EpisodeStore,
) -> list[EpisodeMeta]:
    """Import log files into ``store``: all-or-nothing over the files.

    Every episode of every file is read and validated first (a ``LogImportError`` /
    ``MappingError`` leaves the store untouched); only then are they appended, in file
    order. Returns the stored metadata (ids set). All episodes are held in memory until
    appended.
    """
    mapping = load_mapping(mapping)
    check_against_store(mapping, store)
    episodes = read_logs(
        paths, mapping, sensor_order=list(store.sensors), control_order=store.controls
    )
    return append_episodes(store, episodes)


def append_episodes(
    store: EpisodeStore, episodes: Iterable[tuple[TensorDict, EpisodeMeta]]
) -> list[EpisodeMeta]:
    """Append already-validated episodes to ``store`` as one atomic change."""
    return store.extend(list(episodes))


def create_store(
    root: str | Path, mapping: LogMapping, *, description: str = "", exist_ok: bool = False
) -> EpisodeStore:
    """A new dataset with the mapping's sensors (and units) and controls, in mapping order."""
    return EpisodeStore.create(
        root,
        sensors={name: spec.unit for name, spec in mapping.sensors.items()},
        controls=list(mapping.controls),
        description=description,
        exist_ok=exist_ok,
    )


def _as_paths(paths: str | Path | Iterable[str | Path]) -> list[Path]:
    if isinstance(paths, str | Path):
        return [Path(paths)]
    return [Path(p) for p in paths]


# ---------------------------------------------------------------------------- CLI
def main(argv: Sequence[str] | None = None) -> None:
    """``python -m pilerl.data.importers --mapping m.yaml --dataset DIR LOG...``."""
    parser = argparse.ArgumentParser(description="Import machine logs into a pilerl dataset.")
    parser.add_argument("logs", nargs="+", type=Path, help=".csv / .parquet / .h5 files")
    parser.add_argument("--mapping", required=True, type=Path, help="mapping YAML")
    parser.add_argument(
        "--dataset",
        required=True,
        type=Path,
        help="dataset directory (created from the mapping when it does not exist)",
    )
    parser.add_argument("--description", default="", help="description of a new dataset")
    args = parser.parse_args(argv)
    try:
        mapping = load_mapping(args.mapping)
        if (args.dataset / "index.json").exists():
            store = EpisodeStore.open(args.dataset, writable=True)
            metas = import_logs(args.logs, mapping, store)
        else:  # check every log before the dataset directory is created
            episodes = read_logs(args.logs, mapping)
            store = create_store(args.dataset, mapping, description=args.description)
            metas = append_episodes(store, episodes)
    except SchemaError as error:  # LogImportError, MappingError: the message says where
        raise SystemExit(f"error: {error}") from None
    print(
        f"{args.dataset}: imported {len(metas)} episodes "
        f"({sum(m.n_samples for m in metas)} samples); {len(store)} in the dataset"
    )


if __name__ == "__main__":
    main()
