"""Column-store logs: Parquet (one column per signal) and HDF5 (one 1-D dataset per column
in one group)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import LogImportError, first_line
from ..mapping import ColumnRequest, LogMapping
from .base import LogTable, check_rows, resolve_columns, split_unit

PARQUET_SUFFIXES = (".parquet", ".pq")
HDF5_SUFFIXES = (".h5", ".hdf5")
# numbers, booleans and text; anything else (opaque, compound, references...) is refused
HDF5_KINDS = frozenset("biufSOU")


def read_parquet(path: Path, mapping: LogMapping, requests: Sequence[ColumnRequest]) -> LogTable:
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        schema = pq.read_schema(path)
        names = resolve_columns(path, requests, schema.names)
        check_rows(path, pq.ParquetFile(path).metadata.num_rows)
        table = pq.read_table(path, columns=list(dict.fromkeys(names.values()))).to_pandas()
    except LogImportError:
        raise
    except (pa.ArrowException, OSError, ValueError) as error:
        raise LogImportError(path, f"unreadable Parquet ({first_line(error)})") from None
    frame = pd.DataFrame({name: table[column].to_numpy() for name, column in names.items()})
    for name, column in names.items():
        if frame[name].dtype == object and any(
            isinstance(v, list | np.ndarray) for v in frame[name].head(1)
        ):
            raise LogImportError(path, "a list per row; expected one value per row", column=column)
    units = {n: u for n, c in names.items() if (u := split_unit(c)[1])}
    return LogTable(path, frame, names, units=units)


def read_hdf5(path: Path, mapping: LogMapping, requests: Sequence[ColumnRequest]) -> LogTable:
    import h5py

    group_name = mapping.hdf5_group
    try:
        with h5py.File(path, "r") as h5:
            group = h5.get(group_name)
            if not isinstance(group, h5py.Group):
                raise LogImportError(path, f"no HDF5 group {group_name!r}")
            available = [k for k, v in group.items() if isinstance(v, h5py.Dataset)]
            names = resolve_columns(path, requests, available)
            data = {
                name: _hdf5_column(path, column, group[column]) for name, column in names.items()
            }
            units = {n: _hdf5_unit(group[c]) for n, c in names.items()}
    except LogImportError:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as error:
        raise LogImportError(path, f"unreadable HDF5 ({first_line(error)})") from None
    n_rows = max(len(v) for v in data.values())
    for name, values in data.items():
        if len(values) != n_rows:
            raise LogImportError(
                path,
                f"no value: the column has {len(values)} rows, others have up to {n_rows}",
                column=names[name],
                row=len(values) + 1,
            )
    units = {n: u for n, u in units.items() if u}
    return LogTable(path, pd.DataFrame(data), names, units=units)


def _hdf5_unit(dataset) -> str | None:  # noqa: ANN001 - h5py.Dataset
    unit = dataset.attrs.get("unit", dataset.attrs.get("units"))
    if isinstance(unit, bytes):
        unit = unit.decode("utf-8", "replace")
    return unit if isinstance(unit, str) and unit else None


def _hdf5_column(path: Path, column: str, dataset) -> np.ndarray:  # noqa: ANN001
    import h5py

    kind = dataset.dtype.kind
    vlen_not_text = kind == "O" and h5py.check_string_dtype(dataset.dtype) is None
    if kind not in HDF5_KINDS or dataset.dtype.names is not None or vlen_not_text:
        raise LogImportError(
            path,
            f"unsupported HDF5 dtype {dataset.dtype} ({_kind_name(dataset.dtype)}); "
            "expected numbers, booleans or text",
            column=column,
        )
    shape = dataset.shape
    if shape is None or not (len(shape) == 1 or (len(shape) == 2 and shape[1] == 1)):
        raise LogImportError(path, f"expected a 1-D dataset, got shape {shape}", column=column)
    check_rows(path, shape[0], where=f"column {column!r} ")
    values = dataset[()]
    if values.ndim == 2:
        values = values[:, 0]
    if values.dtype.kind == "S":
        values = np.array([v.decode("utf-8", "replace") for v in values], dtype=object)
    elif values.dtype.kind == "O":
        values = np.array(
            [v.decode("utf-8", "replace") if isinstance(v, bytes) else v for v in values],
            dtype=object,
        )
    return values


def _kind_name(dtype: np.dtype) -> str:
    if dtype.names is not None:
        return "compound"
    if dtype.kind == "O":
        return "references or variable-length arrays"
    return {"V": "opaque", "c": "complex", "M": "date", "m": "time delta"}.get(
        dtype.kind, f"kind {dtype.kind!r}"
    )
