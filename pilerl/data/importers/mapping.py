"""The column mapping: where each pilerl signal is in a log and how to convert it.

A ``LogMapping`` is a tree of dataclasses, loaded from YAML (``load_mapping``: strict
loader, see ``safe_yaml``), a dict or a Hydra ``DictConfig``. The dataclasses are the
schema of an OmegaConf structured config: merging the data into it types every value and
refuses unknown, missing and mistyped fields; ``check_mapping`` then checks the values as
a whole before any log is read. Every problem is a ``MappingError`` naming the file (or
``mapping``) and the field (``mapping.sensors.boom_angle.range``).
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import json
import math
import re
import types
import typing
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import ConfigKeyError, OmegaConfBaseException, UnsupportedValueType

from pilerl.io import write_text_atomic

from . import units as unit_table
from .errors import MappingError
from .safe_yaml import YamlError, load_yaml_file

TIME_FORMATS = ("auto", "number", "iso")
_INTERPOLATION = re.compile(r"(\\*)\$\{")  # backslashes before "${": OmegaConf's escapes
CSV_DELIMITERS = ("auto", ",", ";", "\t", "|", " ")
CSV_DECIMALS = ("auto", ".", ",")


@dataclass
class SensorSpec:
    """Where one sensor's reading is in a log and how to convert it.

    Attributes:
        column: source column name (as the header spells it; a trailing ``[unit]`` in the
            header may be left out).
        unit: pilerl unit of the converted value (``rad``, ``MPa``...); must equal the
            dataset's unit for this sensor.
        range: the machine's own physical range ``[low, high]`` in ``unit``; a converted
            reading outside it is rejected (``-.inf`` / ``.inf`` in YAML for an open end).
            It is recorded with the dataset; the simulator's ranges play no part here.
        scale: multiplier applied after the unit conversion (calibration; 1 by default).
        offset: added last, in ``unit`` (e.g. a joint's zero offset).
        source_unit: unit of the raw values (``bar``, ``deg``, ``%``); None takes the unit
            the file declares (a units row, ``name [unit]`` header, MDF / DBC units), if
            any. ``raw``: no unit conversion, only ``scale`` and ``offset``.
        aliases: other column names that hold this sensor (first found is used).
    """

    column: str
    unit: str
    range: list[float]
    scale: float = 1.0
    offset: float = 0.0
    source_unit: str | None = None
    aliases: list[str] = field(default_factory=list)

    def convert(self, raw: np.ndarray) -> np.ndarray:
        """Raw readings already in ``unit`` -> calibrated value: ``raw * scale + offset``."""
        return raw * self.scale + self.offset


@dataclass
class ControlSpec:
    """Where one control is in a log; the converted value must lie in [-1, 1].

    Attributes:
        column: source column name.
        scale: multiplier after the unit conversion (e.g. 1/100 for % without a unit).
        offset: added last.
        source_unit: ``%`` (100 % -> 1), ``permille``, ``1``; None takes the file's unit.
        aliases: other column names that hold this control.
    """

    column: str
    scale: float = 1.0
    offset: float = 0.0
    source_unit: str | None = None
    aliases: list[str] = field(default_factory=list)

    def convert(self, raw: np.ndarray) -> np.ndarray:
        """Raw commands (unit-converted) -> normalised control: ``raw * scale + offset``."""
        return raw * self.scale + self.offset


@dataclass
class TimeSpec:
    """The time base of a log.

    Attributes:
        column: time column (any origin), or None when the log has no time column.
        scale: seconds per raw time unit (0.001 for milliseconds); leave 1 when ``unit``
            or the file gives the unit.
        rate_hz: sampling rate [Hz]; required without a time column (time = row /
            rate_hz) and for message logs (MCAP, bags, CAN, MDF: the grid the signals are
            sampled onto); otherwise the nominal rate written to the metadata (default:
            1 / median interval).
        start_at_zero: subtract the episode's first time, so that ``time_s`` is the time
            since the episode start (the schema's meaning); False keeps the log's times.
        unit: unit of a numeric time column (``ms``, ``s``, ``us``); None: the file's
            unit, else ``scale``.
        format: ``number``, ``iso`` (ISO 8601 timestamps such as
            ``2025-02-11T10:15:03.250``) or ``auto`` (ISO when the first cell is a date).
        aliases: other names of the time column.
        resample_hz: resample every episode onto this rate (sensors linearly, controls
            and flags by holding the last value); None keeps the rows as logged.
        max_gap_s: refuse a log with an interval longer than this [s] (dropped samples);
            None only reports gaps in the quality report.
    """

    column: str | None = None
    scale: float = 1.0
    rate_hz: float | None = None
    start_at_zero: bool = True
    unit: str | None = None
    format: str = "auto"
    aliases: list[str] = field(default_factory=list)
    resample_hz: float | None = None
    max_gap_s: float | None = None


@dataclass
class CsvSpec:
    """How a CSV / TSV file is written.

    Attributes:
        delimiter: field separator, or ``auto`` (detected from the header and first rows).
        decimal: decimal mark ``.`` or ``,``, or ``auto`` (``,`` when numbers look like
            ``0,25`` and the separator is not a comma).
        comment: lines starting with this are skipped (None: no comment lines).
        skip_rows: lines before the header to skip (a logger's preamble).
        units_row: the line after the header holds each column's unit (``ms;deg;bar``).
        encoding: text encoding; ``auto`` = UTF-8 with or without a BOM.
        final_newline: a complete file ends with a newline; without one the last row is
            reported as truncated. False for loggers that write no final newline.
    """

    delimiter: str = "auto"
    decimal: str = "auto"
    comment: str | None = "#"
    skip_rows: int = 0
    units_row: bool = False
    encoding: str = "auto"
    final_newline: bool = True


@dataclass
class CanSpec:
    """CAN logs (BLF / ASC / candump): the DBC file that decodes their frames.

    Attributes:
        dbc: path of the DBC file (relative paths: from the mapping file's folder).
    """

    dbc: str | None = None


@dataclass
class MetadataSpec:
    """Episode-level metadata of imported logs (``EpisodeMeta`` fields).

    Attributes:
        condition: condition label (``summer``, ``site-A-frozen``...).
        condition_params: known material / ground / hydraulics parameters: plain JSON
            values only (text, finite numbers, true/false, lists and mappings of them).
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


@dataclass(frozen=True)
class ColumnRequest:
    """A column the mapping reads: its name in the mapping and every name it may have."""

    name: str
    candidates: tuple[str, ...]


@dataclass
class LogMapping:
    """How a machine log maps onto pilerl's episodes (see ``pilerl.data.importers``).

    Attributes:
        sensors: pilerl sensor name -> ``SensorSpec``.
        controls: pilerl control name -> ``ControlSpec``.
        time: the time base.
        episode_column: column whose value changes between episodes; None = one file is
            one episode.
        hdf5_group: HDF5 group holding one dataset per column.
        csv: how CSV / TSV files are written.
        can: the DBC file for CAN logs.
        metadata: episode metadata.
    """

    sensors: dict[str, SensorSpec]
    controls: dict[str, ControlSpec]
    time: TimeSpec = field(default_factory=TimeSpec)
    episode_column: str | None = None
    hdf5_group: str = "/"
    csv: CsvSpec = field(default_factory=CsvSpec)
    can: CanSpec = field(default_factory=CanSpec)
    metadata: MetadataSpec = field(default_factory=MetadataSpec)

    def requests(self) -> list[ColumnRequest]:
        """Every source column the mapping reads, once each, in checking order."""
        meta = self.metadata
        specs: list[tuple[str | None, Iterable[str]]] = [
            (self.episode_column, ()),
            (self.time.column, self.time.aliases),
            *((s.column, s.aliases) for s in self.sensors.values()),
            *((c.column, c.aliases) for c in self.controls.values()),
            (meta.fill_fraction_column, ()),
            (meta.success_column, ()),
        ]
        out: dict[str, ColumnRequest] = {}
        for name, aliases in specs:
            if name is not None and name not in out:
                out[name] = ColumnRequest(name, tuple(dict.fromkeys([name, *aliases])))
        return list(out.values())

    def columns(self) -> list[str]:
        """Every source column name the mapping reads, once each, in checking order."""
        return [r.name for r in self.requests()]


# ---------------------------------------------------------------------------- load / save
def load_mapping(source: LogMapping | Mapping | str | Path) -> LogMapping:
    """A checked ``LogMapping`` from a YAML file, a plain dict / DictConfig, or a mapping.

    Raises ``MappingError`` naming the field on unknown, missing or mistyped fields, and
    naming the line on YAML that is not plain data (duplicate keys, alias bombs, not
    UTF-8 / UTF-16 text).
    """
    if isinstance(source, LogMapping):
        check_mapping(source)
        return source
    if isinstance(source, str | Path):
        path = Path(source)
        try:
            data = load_yaml_file(path)
        except (OSError, YamlError) as error:
            raise MappingError(f"{path}: cannot read the mapping ({error})") from None
        mapping = mapping_from_dict(data, where=str(path))
        if mapping.can.dbc is not None and not Path(mapping.can.dbc).is_absolute():
            mapping.can.dbc = str((path.parent / mapping.can.dbc).resolve())
        return mapping
    return mapping_from_dict(source)


def mapping_from_dict(data: Mapping, *, where: str = "mapping") -> LogMapping:
    """Build and check a ``LogMapping`` from plain data (YAML / JSON / DictConfig)."""
    if isinstance(data, DictConfig):
        data = OmegaConf.to_container(data, resolve=True)
    mapping = _structured(data, where)
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


# ---------------------------------------------------------------------------- checks
def check_mapping(mapping: LogMapping, *, where: str = "mapping") -> None:
    """Raise ``MappingError`` naming the field if a value makes no sense."""
    if not mapping.sensors:
        raise MappingError(f"{where}.sensors: at least one sensor is needed")
    for name, sensor in mapping.sensors.items():
        path = f"{where}.sensors.{name}"
        _check_column_names(sensor.column, sensor.aliases, path)
        _check_scale(sensor.scale, sensor.offset, path)
        if len(sensor.range) != 2 or not sensor.range[0] < sensor.range[1]:
            raise MappingError(
                f"{path}.range: expected [low, high] with low < high, got {sensor.range}"
            )
        _check_unit(sensor.unit, f"{path}.unit", allow_unknown=True)
        if sensor.source_unit is not None:
            _check_source_unit(sensor.source_unit, sensor.unit, f"{path}.source_unit")
    for name, control in mapping.controls.items():
        path = f"{where}.controls.{name}"
        _check_column_names(control.column, control.aliases, path)
        _check_scale(control.scale, control.offset, path)
        if control.source_unit is not None:
            _check_source_unit(control.source_unit, "1", f"{path}.source_unit")
    _check_time(mapping.time, f"{where}.time")
    if mapping.episode_column is not None:
        _check_column_name(mapping.episode_column, f"{where}.episode_column")
    _check_csv(mapping.csv, f"{where}.csv")
    _check_metadata(mapping.metadata, f"{where}.metadata")


def check_against_store(mapping: LogMapping, store) -> None:  # noqa: ANN001 - EpisodeStore
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
    if not column or not column.strip():
        raise MappingError(f"{path}: empty column name")


def _check_column_names(column: str, aliases: list[str], path: str) -> None:
    _check_column_name(column, f"{path}.column")
    for i, alias in enumerate(aliases):
        _check_column_name(alias, f"{path}.aliases[{i}]")


def _check_scale(scale: float, offset: float, path: str) -> None:
    if not math.isfinite(scale) or scale == 0.0:
        raise MappingError(f"{path}.scale: must be finite and non-zero, got {scale}")
    if not math.isfinite(offset):
        raise MappingError(f"{path}.offset: must be finite, got {offset}")


def _check_unit(label: str, path: str, *, allow_unknown: bool = False) -> None:
    try:
        unit_table.normalise(label)
    except unit_table.UnitError as error:
        if not allow_unknown:
            raise MappingError(f"{path}: {error}") from None


def _check_source_unit(source: str, target: str, path: str) -> None:
    if source == unit_table.RAW:
        return
    try:
        unit_table.conversion(source, target)
    except unit_table.UnitError as error:
        raise MappingError(f"{path}: {error}; use 'raw' with scale/offset instead") from None


def _check_time(time: TimeSpec, path: str) -> None:
    if time.column is None and time.rate_hz is None:
        raise MappingError(f"{path}: give a time column or rate_hz")
    if time.column is not None:
        _check_column_names(time.column, time.aliases, path)
    if not (math.isfinite(time.scale) and time.scale > 0):
        raise MappingError(f"{path}.scale: seconds per raw unit must be > 0, got {time.scale}")
    for name in ("rate_hz", "resample_hz", "max_gap_s"):
        value = getattr(time, name)
        if value is not None and not (math.isfinite(value) and value > 0):
            raise MappingError(f"{path}.{name}: must be finite and > 0, got {value}")
    if time.format not in TIME_FORMATS:
        raise MappingError(
            f"{path}.format: expected one of {list(TIME_FORMATS)}, got {time.format!r}"
        )
    if time.unit is not None:
        if time.scale != 1.0:
            raise MappingError(f"{path}: give unit or scale, not both (both convert to seconds)")
        try:
            unit_table.conversion(time.unit, "s")
        except unit_table.UnitError as error:
            raise MappingError(f"{path}.unit: {error}") from None


def _check_csv(csv: CsvSpec, path: str) -> None:
    if csv.delimiter not in CSV_DELIMITERS:
        raise MappingError(
            f"{path}.delimiter: expected one of {list(CSV_DELIMITERS)}, got {csv.delimiter!r}"
        )
    if csv.decimal not in CSV_DECIMALS:
        raise MappingError(
            f"{path}.decimal: expected one of {list(CSV_DECIMALS)}, got {csv.decimal!r}"
        )
    if csv.decimal == "," and csv.delimiter == ",":
        raise MappingError(f"{path}: decimal ',' needs a separator other than ','")
    if csv.comment is not None and len(csv.comment) != 1:
        raise MappingError(f"{path}.comment: one character or null, got {csv.comment!r}")
    if csv.skip_rows < 0:
        raise MappingError(f"{path}.skip_rows: must be >= 0, got {csv.skip_rows}")
    if csv.encoding != "auto":
        import codecs

        try:
            codecs.lookup(csv.encoding)
        except LookupError:
            raise MappingError(f"{path}.encoding: unknown encoding {csv.encoding!r}") from None


def _check_metadata(meta: MetadataSpec, path: str) -> None:
    if meta.fill_fraction is not None and meta.fill_fraction_column is not None:
        raise MappingError(f"{path}: give fill_fraction or fill_fraction_column, not both")
    if meta.success is not None and meta.success_column is not None:
        raise MappingError(f"{path}: give success or success_column, not both")
    if meta.fill_fraction is not None and not (
        math.isfinite(meta.fill_fraction) and meta.fill_fraction >= 0
    ):
        raise MappingError(f"{path}.fill_fraction: must be >= 0, got {meta.fill_fraction}")
    _check_json_value(meta.condition_params, f"{path}.condition_params")


def _check_json_value(value: object, path: str) -> None:
    """Plain JSON only: the dataset index is strict JSON (no NaN, no dates)."""
    if value is None or isinstance(value, str | bool):
        return
    if isinstance(value, int | float):
        if not math.isfinite(value):
            raise MappingError(f"{path}: {value} is not a finite number")
        return
    if isinstance(value, list | tuple):
        for i, item in enumerate(value):
            _check_json_value(item, f"{path}[{i}]")
        return
    if isinstance(value, Mapping):
        for key, item in value.items():
            if not isinstance(key, str):
                raise MappingError(f"{path}: key {key!r} is not text")
            _check_json_value(item, f"{path}.{key}")
        return
    raise MappingError(
        f"{path}: {value!r} ({type(value).__name__}) is not plain JSON; "
        "quote dates and other values as text"
    )


# -- typed construction from plain data: OmegaConf structured configs -------------------
def _structured(data: Mapping, where: str) -> LogMapping:
    """``LogMapping`` from plain data, typed and checked by OmegaConf's structured configs.

    ``OmegaConf.structured(LogMapping)`` is the schema: merging the data into it refuses
    unknown fields and values that do not convert to the declared types; fields left
    ``MISSING`` are the required ones the data did not give. OmegaConf's errors are
    reworded to name the field under ``where`` (the file, or ``mapping``).
    """
    if not isinstance(data, Mapping):
        raise MappingError(f"{where}: expected a mapping of fields, got {type(data).__name__}")
    try:  # plain JSON data: the same text gives the same mapping, typed once per process
        text = json.dumps(data, sort_keys=True)
    except (TypeError, ValueError):
        text = None  # dates and other objects: the merge below names the field
    if text is not None and json.loads(text) == data:  # JSON holds all of it (str keys...)
        try:
            return copy.deepcopy(_typed_from_json(text))
        except MappingError:
            pass  # reported below with ``where``
    return _typed(data, where)


@functools.lru_cache(maxsize=64)
def _typed_from_json(text: str) -> LogMapping:
    """``_typed`` of plain JSON text, memoised: OmegaConf's merge costs ~20 ms a mapping."""
    return _typed(json.loads(text), "mapping")


@functools.cache
def _schema() -> DictConfig:
    """``OmegaConf.structured(LogMapping)``, built once (``merge`` copies it, never changes it)."""
    return OmegaConf.structured(LogMapping)


def _typed(data: Mapping, where: str) -> LogMapping:
    """The merge of ``data`` into the ``LogMapping`` schema; ``MappingError`` names the field."""
    try:
        config = OmegaConf.merge(_schema(), _literal(data))
    except OmegaConfBaseException as error:
        raise MappingError(_describe(error, where)) from None
    missing = _first_missing(config, where)
    if missing is not None:
        node, names = missing
        raise MappingError(f"{node}: missing required field(s) {names}")
    return OmegaConf.to_object(config)


def _literal(value: object) -> object:
    """``value`` with every ``${`` in its text escaped: a mapping's text is taken as
    written (a column named ``x${1}``), never as an OmegaConf interpolation. A Hydra
    config's interpolations were resolved before (``mapping_from_dict``)."""
    if isinstance(value, str):
        return _INTERPOLATION.sub(lambda m: m.group(1) * 2 + "\\${", value)
    if isinstance(value, Mapping):
        return {key: _literal(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_literal(item) for item in value]
    return value


def _describe(error, where: str) -> str:  # noqa: ANN001 - an OmegaConfBaseException
    """One line naming the field for an error raised by ``OmegaConf.merge``."""
    key = str(error.full_key)
    path = f"{where}.{key}" if key else where
    schema = error.object_type
    if isinstance(error, ConfigKeyError) and dataclasses.is_dataclass(schema):
        parent = path.rsplit(".", 1)[0] if "." in key else where
        known = [f.name for f in dataclasses.fields(schema)]
        return f"{parent}: unknown field(s) [{error.key!r}]; known fields: {known}"
    if isinstance(error, UnsupportedValueType):
        value = error.value
        return (
            f"{path}: {value!r} ({type(value).__name__}) is not plain JSON; "
            "quote dates and other values as text"
        )
    hints = typing.get_type_hints(schema) if dataclasses.is_dataclass(schema) else {}
    if error.key in hints:
        expected = _type_name(hints[error.key])
        return f"{path}: expected {expected}, got {error.value!r}"
    return f"{path}: {str(error.msg).splitlines()[0]}"


def _type_name(annotation: object) -> str:
    """``float``, ``str or null``, ``list[float]``: a field's type as the YAML author reads it."""
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) in (types.UnionType, typing.Union):
        names = [_type_name(a) for a in args if a is not type(None)]
        return " or ".join(names) + (" or null" if type(None) in args else "")
    if args:
        return f"{typing.get_origin(annotation).__name__}[{', '.join(map(_type_name, args))}]"
    return getattr(annotation, "__name__", str(annotation))


def _first_missing(config, path: str) -> tuple[str, list[str]] | None:  # noqa: ANN001
    """The first node (in field order) with required fields left unset, and their names."""
    names = [str(k) for k in config if OmegaConf.is_missing(config, k)]
    if names:
        return path, names
    for key in config:
        child = config[key]
        if isinstance(child, DictConfig):
            found = _first_missing(child, f"{path}.{key}")
            if found is not None:
                return found
    return None
