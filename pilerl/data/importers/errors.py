"""The two errors of the importers: a bad mapping and a bad log file."""

from __future__ import annotations

from pathlib import Path

from pilerl.data.schema import SchemaError

ROWS = "1-based data row"


class MappingError(SchemaError):
    """A column mapping is malformed or does not fit the store; the message names the field."""


class LogImportError(SchemaError):
    """A log file cannot be imported; names the file, and the column and row where they apply.

    Attributes:
        file: the log file, as given.
        column: the source column (as the file spells it), or None (a whole-file problem).
        row: 1-based data row, or None (a whole-column or whole-file problem).
        line: 1-based line of the file where that row starts (text formats), or None.
        problem: what is wrong.
    """

    def __init__(
        self,
        file: str | Path,
        problem: str,
        *,
        column: str | None = None,
        row: int | None = None,
        line: int | None = None,
    ) -> None:
        self.file, self.column, self.row, self.line = str(file), column, row, line
        self.problem = problem
        where = []
        if column is not None:
            where.append(f"column {column!r}")
        if row is not None:
            where.append(f"row {row} ({ROWS})" + (f" at line {line}" if line else ""))
        elif line is not None:
            where.append(f"line {line}")
        prefix = f"{file}: " + (", ".join(where) + ": " if where else "")
        super().__init__(prefix + problem)

    def __reduce__(self):  # keep the exception picklable (multiprocessing, pytest-xdist)
        return _rebuild_error, (self.file, self.problem, self.column, self.row, self.line)


def _rebuild_error(
    file: str, problem: str, column: str | None, row: int | None, line: int | None = None
) -> LogImportError:
    return LogImportError(file, problem, column=column, row=row, line=line)


def first_line(error: BaseException) -> str:
    """``Type: first line of the message`` of a library's exception, for our messages."""
    text = str(error).strip().splitlines()
    return f"{type(error).__name__}: {text[0] if text else ''}"
