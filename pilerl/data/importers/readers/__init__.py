"""One reader per log format, chosen by the file's extension; each returns a ``LogTable``
with the mapping's columns, as read (no conversion)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from ..errors import LogImportError
from ..mapping import ColumnRequest, LogMapping
from .base import LogTable, resolve_columns, split_unit
from .can import CAN_SUFFIXES, read_can
from .delimited import CSV_SUFFIXES, read_delimited
from .mdf import MDF_SUFFIXES, read_mdf
from .ros import BAG_SUFFIXES, MCAP_SUFFIXES, read_bag, read_mcap
from .tables import HDF5_SUFFIXES, PARQUET_SUFFIXES, read_hdf5, read_parquet

Reader = Callable[[Path, LogMapping, Sequence[ColumnRequest]], LogTable]
READERS: dict[tuple[str, ...], Reader] = {
    CSV_SUFFIXES: read_delimited,
    PARQUET_SUFFIXES: read_parquet,
    HDF5_SUFFIXES: read_hdf5,
    MCAP_SUFFIXES: read_mcap,
    BAG_SUFFIXES: read_bag,
    CAN_SUFFIXES: read_can,
    MDF_SUFFIXES: read_mdf,
}

__all__ = ["LogTable", "known_suffixes", "read_log", "resolve_columns", "split_unit"]


def known_suffixes() -> list[str]:
    return [s for suffixes in READERS for s in suffixes]


def read_log(path: str | Path, mapping: LogMapping) -> LogTable:
    """The mapping's columns of one log file; format by extension (a folder holding
    ``metadata.yaml`` is a ROS 2 bag).

    Raises ``LogImportError`` for a missing, empty, corrupt or unreadable file, or a
    missing column.
    """
    path = Path(path)
    requests = mapping.requests()
    if path.is_dir() and (path / "metadata.yaml").is_file():
        table = read_bag(path, mapping, requests)
    elif not path.is_file():
        raise LogImportError(path, "no such file")
    elif path.stat().st_size == 0:
        raise LogImportError(path, "empty file (0 bytes)")
    else:
        name = path.name.lower()
        reader = next((r for suffixes, r in READERS.items() if name.endswith(suffixes)), None)
        if reader is None:
            raise LogImportError(path, f"unknown log format; expected one of {known_suffixes()}")
        table = reader(path, mapping, requests)
    if len(table) == 0:
        raise LogImportError(path, "empty file (no data rows)")
    return table
