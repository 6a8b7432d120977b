"""What every reader returns (``LogTable``) and the column lookup they share."""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .. import units as unit_table
from ..errors import LogImportError
from ..mapping import ColumnRequest

MAX_ROWS = 50_000_000  # a declared length beyond this is a malformed file, not a log
_UNIT_SUFFIX = re.compile(r"^(?P<name>.*?)\s*[\[(](?P<unit>[^\[\]()]*)[\])]\s*$")


@dataclass
class LogTable:
    """The mapped columns of one log, as read (no conversion).

    Attributes:
        path: the file.
        frame: one column per ``ColumnRequest.name`` (mapping names), one row per sample.
        source_names: mapping name -> the column's name in the file (for messages).
        units: mapping name -> unit label the file declares for it (units row, header
            ``name [unit]``, MDF channel unit, DBC signal unit).
        lines: file line of each data row (text formats), or None.
        notes: what the reader did that the quality report should say (resampling...).
        signal_gaps: per mapping name, the longest interval between two messages [s]
            (message logs, before they are sampled onto the grid).
    """

    path: Path
    frame: pd.DataFrame
    source_names: dict[str, str]
    units: dict[str, str] = field(default_factory=dict)
    lines: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)
    signal_gaps: dict[str, float] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.frame)

    def error(self, problem: str, *, column: str | None = None, row: int | None = None):
        """A ``LogImportError`` for mapping column ``column`` at 1-based data ``row``."""
        line = None
        if row is not None and self.lines is not None and 0 < row <= len(self.lines):
            line = int(self.lines[row - 1])
        name = None if column is None else self.source_names.get(column, column)
        return LogImportError(self.path, problem, column=name, row=row, line=line)


def split_unit(header: str) -> tuple[str, str | None]:
    """``"p_boom [bar]"`` -> ``("p_boom", "bar")``. Only a unit the converter knows counts:
    ``"Pressure (front)"`` is a name, -> ``("Pressure (front)", None)``."""
    match = _UNIT_SUFFIX.match(header)
    if match and match.group("name").strip():
        try:
            unit_table.normalise(match.group("unit"))
        except unit_table.UnitError:
            return header, None
        return match.group("name").strip(), match.group("unit").strip()
    return header, None


def _normal(name: str) -> str:
    return " ".join(split_unit(str(name))[0].split()).casefold()


def resolve_columns(
    path: Path, requests: Sequence[ColumnRequest], available: Sequence[str]
) -> dict[str, str]:
    """Mapping name -> file column, for every request.

    A request matches a file column exactly, else after dropping a ``[unit]`` suffix,
    case and repeated spaces; the first candidate (column, then aliases) that matches
    wins. Two file columns matching one name is an error, as is no match.
    """
    available = [str(a) for a in available]
    normal: dict[str, list[str]] = {}
    for name in available:
        normal.setdefault(_normal(name), []).append(name)
    out: dict[str, str] = {}
    for request in requests:
        found = None
        for candidate in request.candidates:
            if available.count(candidate) > 1:
                raise LogImportError(
                    path, f"the header names {candidate!r} twice; rename one", column=request.name
                )
            if candidate in available:
                found = candidate
                break
            matches = normal.get(_normal(candidate), [])
            if len(matches) > 1:
                raise LogImportError(
                    path,
                    f"ambiguous: columns {matches} all match {candidate!r}; rename one or "
                    "map the exact header",
                    column=request.name,
                )
            if matches:
                found = matches[0]
                break
        if found is None:
            also = f" (or {list(request.candidates[1:])})" if len(request.candidates) > 1 else ""
            raise LogImportError(
                path, f"missing column{also} (the file has {available})", column=request.name
            )
        out[request.name] = found
    return out


def check_rows(path: Path, n_rows: int, where: str = "") -> None:
    """Refuse a declared length no log has (a malformed header), before allocating."""
    if n_rows > MAX_ROWS:
        raise LogImportError(
            path, f"{where}declares {n_rows} rows, more than {MAX_ROWS}: a malformed file?"
        )
