"""CSV / TSV as data loggers write them.

Handles: ``.gz`` compression (a truncated or corrupt archive is an error, not a
traceback), a preamble (``csv.skip_rows``), comment and blank lines, the separator and
decimal mark (declared or detected), a units row under the header or ``name [unit]``
headers, quoted fields, and truncation: a row with fewer fields than the header, or a
last row without its final newline, is reported as a truncated file at its line.
"""

from __future__ import annotations

import codecs
import csv
import gzip
import io
import re
import zlib
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import LogImportError
from ..mapping import ColumnRequest, CsvSpec, LogMapping
from .base import LogTable, check_rows, resolve_columns, split_unit

CSV_SUFFIXES = (".csv", ".tsv", ".csv.gz", ".tsv.gz")
DELIMITERS = ("\t", ";", ",", "|")
SNIFF_ROWS = 50
MAX_TEXT_BYTES = 2 << 30  # 2 GiB of text: larger logs should be split or stored as Parquet
_COMMA_NUMBER = re.compile(r"^\s*[+-]?\d+,\d+(?:[eE][+-]?\d+)?\s*$")
_POINT_NUMBER = re.compile(r"^\s*[+-]?\d*\.\d+(?:[eE][+-]?\d+)?\s*$")


def read_delimited(path: Path, mapping: LogMapping, requests: Sequence[ColumnRequest]) -> LogTable:
    spec = mapping.csv
    text = _decode(path, _read_bytes(path), spec.encoding)
    lines = text.splitlines(keepends=True)
    kept = _content_lines(lines, spec)
    if not kept:
        raise LogImportError(path, "empty file (no header)")
    ends_with_newline = kept[-1][1].endswith(("\n", "\r"))
    delimiter = spec.delimiter if spec.delimiter != "auto" else _sniff_delimiter(kept)
    rows = list(_parse(path, kept, delimiter))
    (_, header), body = rows[0], rows[1:]
    header = [h.strip() for h in header]
    width = len(header)
    units: dict[str, str] = {}
    names = resolve_columns(path, requests, header)
    index = {name: header.index(column) for name, column in names.items()}
    for name, column in names.items():
        unit = split_unit(column)[1]
        if unit:
            units[name] = unit
    if spec.units_row:
        if not body:
            raise LogImportError(path, "no units row under the header (csv.units_row is true)")
        units_line, unit_cells = body[0]
        body = body[1:]
        if sum(_is_number(c) for c in unit_cells) > len(unit_cells) // 2:
            raise LogImportError(
                path,
                "csv.units_row is true, but the line under the header holds numbers, not units",
                line=units_line,
            )
        for name, i in index.items():
            cell = unit_cells[i].strip() if i < len(unit_cells) else ""
            if cell:
                units[name] = cell
        if len(unit_cells) != width:
            raise LogImportError(
                path,
                f"units row has {len(unit_cells)} fields, the header has {width}",
                line=units_line,
            )
    _check_widths(path, body, width, ends_with_newline, spec)
    if not body:
        raise LogImportError(path, "empty file (no data rows)")
    check_rows(path, len(body))
    frame = pd.DataFrame(
        {name: np.array([cells[i] for _, cells in body], dtype=object) for name, i in index.items()}
    )
    decimal = spec.decimal if spec.decimal != "auto" else _sniff_decimal(path, frame, delimiter)
    if decimal == ",":
        frame = frame.apply(lambda col: col.str.replace(",", ".", regex=False))
    table = LogTable(
        path,
        frame,
        names,
        units=units,
        lines=np.array([line for line, _ in body], dtype=np.int64),
    )
    if spec.delimiter == "auto" or spec.decimal == "auto":
        table.notes.append(
            f"separator {_show(delimiter)} and decimal mark {decimal!r}"
            + (" (detected)" if spec.delimiter == "auto" else "")
        )
    return table


# ---------------------------------------------------------------------------- bytes / text
def _read_bytes(path: Path) -> bytes:
    if not path.name.lower().endswith(".gz"):
        if path.stat().st_size > MAX_TEXT_BYTES:
            raise LogImportError(
                path, f"larger than {MAX_TEXT_BYTES} bytes; split the log or store it as Parquet"
            )
        return path.read_bytes()
    try:
        with gzip.open(path, "rb") as stream:
            data = stream.read(MAX_TEXT_BYTES + 1)
    except EOFError:
        raise LogImportError(
            path, "truncated gzip archive (it ends before its data does)"
        ) from None
    except (gzip.BadGzipFile, zlib.error, OSError) as error:
        raise LogImportError(path, f"corrupt gzip archive ({error})") from None
    if len(data) > MAX_TEXT_BYTES:
        raise LogImportError(
            path,
            f"more than {MAX_TEXT_BYTES} bytes once decompressed (a gzip bomb?); split the log",
        )
    return data


def _decode(path: Path, data: bytes, encoding: str) -> str:
    if encoding == "auto":
        if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
            raise LogImportError(
                path, "unreadable CSV (UTF-16 text); declare csv.encoding: utf-16 in the mapping"
            )
        encoding = "utf-8-sig"
    try:
        text = data.decode(encoding)
    except UnicodeDecodeError as error:
        line = data[: error.start].count(b"\n") + 1
        raise LogImportError(
            path,
            f"unreadable CSV (not {encoding} text: byte 0x{data[error.start]:02x}); "
            "declare csv.encoding (e.g. latin-1) in the mapping",
            line=line,
        ) from None
    if "\x00" in text:
        line = text[: text.index("\x00")].count("\n") + 1
        raise LogImportError(path, "unreadable CSV (binary data: a NUL character)", line=line)
    return text


def _content_lines(lines: list[str], spec: CsvSpec) -> list[tuple[int, str]]:
    """(1-based file line, text) of the header and data lines: preamble, comments and
    blank lines dropped."""
    kept = []
    for number, line in enumerate(lines, start=1):
        if number <= spec.skip_rows:
            continue
        stripped = line.strip()
        if not stripped or (spec.comment is not None and stripped.startswith(spec.comment)):
            continue
        kept.append((number, line))
    return kept


def _show(delimiter: str) -> str:
    return {"\t": "tab", " ": "space"}.get(delimiter, repr(delimiter))


def _sniff_delimiter(kept: list[tuple[int, str]]) -> str:
    """The separator that splits the header into more than one field and the most of the
    first rows into as many fields as the header (a short or cut row does not change the
    choice); on a tie the one giving more fields; ',' if none splits the header."""
    sample = "".join(line for _, line in kept[: SNIFF_ROWS + 1])
    best, best_score = ",", (0, 0)
    for delimiter in DELIMITERS:
        try:
            rows = [r for r in csv.reader(io.StringIO(sample), delimiter=delimiter) if r]
        except csv.Error:
            continue
        width = len(rows[0]) if rows else 0
        if width < 2:
            continue
        score = (sum(len(r) == width for r in rows[1:]), width)
        if score > best_score:
            best, best_score = delimiter, score
    return best


def _parse(
    path: Path, kept: list[tuple[int, str]], delimiter: str
) -> Iterator[tuple[int, list[str]]]:
    """(file line where the record starts, fields) per record; quoted fields may span lines."""
    position = [0]

    def feed() -> Iterator[str]:
        while position[0] < len(kept):
            line = kept[position[0]][1]
            position[0] += 1
            yield line

    reader = csv.reader(feed(), delimiter=delimiter, strict=True)
    while True:
        start = kept[min(position[0], len(kept) - 1)][0]
        try:
            row = next(reader)
        except StopIteration:
            return
        except csv.Error as error:
            line = kept[max(position[0] - 1, 0)][0]
            raise LogImportError(path, f"unreadable CSV ({error})", line=line) from None
        yield start, row


def _check_widths(
    path: Path,
    body: list[tuple[int, list[str]]],
    width: int,
    ends_with_newline: bool,
    spec: CsvSpec,
) -> None:
    for k, (line, cells) in enumerate(body):
        is_last = k == len(body) - 1
        if len(cells) > width:
            raise LogImportError(
                path,
                f"unreadable CSV (row {k + 1} has {len(cells)} fields, the header has {width})",
                line=line,
            )
        if len(cells) < width:
            if is_last and not ends_with_newline:
                raise LogImportError(
                    path,
                    f"truncated file: the last row ends after {len(cells)} of {width} fields "
                    "without a final newline",
                    row=k + 1,
                    line=line,
                )
            raise LogImportError(
                path, f"row has {len(cells)} of {width} fields", row=k + 1, line=line
            )
    if body and not ends_with_newline and spec.final_newline:
        raise LogImportError(
            path,
            "truncated file: the last row has no final newline, so its last field may be cut; "
            "if the logger writes no final newline, set csv.final_newline: false",
            row=len(body),
            line=body[-1][0],
        )


def _is_number(cell: str) -> bool:
    return bool(
        _COMMA_NUMBER.match(cell)
        or _POINT_NUMBER.match(cell)
        or cell.strip().lstrip("+-").isdigit()
    )


def _sniff_decimal(path: Path, frame: pd.DataFrame, delimiter: str) -> str:
    if delimiter == ",":
        return "."
    sample = frame.head(SNIFF_ROWS * 20)
    comma = point = 0
    for column in sample.columns:
        values = sample[column].astype(str)
        comma += int(values.str.match(_COMMA_NUMBER).sum())
        point += int(values.str.match(_POINT_NUMBER).sum())
    if comma and point:
        raise LogImportError(
            path,
            f"cannot tell the decimal mark: {comma} numbers like '0,5' and {point} like "
            "'0.5'; declare csv.decimal in the mapping",
        )
    return "," if comma else "."
