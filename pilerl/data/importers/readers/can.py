"""CAN logs (Vector BLF and ASC, Linux candump ``.log``) decoded with a DBC file.

Every frame whose id the DBC knows is decoded (``cantools``) into its signals, named
``<Message>.<Signal>`` and, where the signal name is unique in the log, ``<Signal>``
too; units come from the DBC. Frames the DBC does not know are counted in the notes.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ..errors import LogImportError, first_line
from ..mapping import ColumnRequest, LogMapping
from .base import LogTable
from .optional import require
from .streams import SignalCollector, sample_onto_grid

CAN_SUFFIXES = (".blf", ".asc", ".log")


def read_can(path: Path, mapping: LogMapping, requests: Sequence[ColumnRequest]) -> LogTable:
    can = require("can", path, "CAN logs")
    cantools = require("cantools", path, "CAN logs")
    if mapping.can.dbc is None:
        raise LogImportError(path, "a CAN log needs a DBC file: set can.dbc in the mapping")
    try:
        database = cantools.database.load_file(mapping.can.dbc)
    except Exception as error:  # noqa: BLE001 - cantools raises many types for a bad DBC
        raise LogImportError(mapping.can.dbc, f"unreadable DBC ({first_line(error)})") from None
    collector = SignalCollector()
    unknown_ids: dict[int, int] = {}
    frame_number = 0
    try:
        with can.LogReader(str(path)) as reader:
            for frame in reader:
                frame_number += 1
                if frame.is_error_frame or frame.is_remote_frame:
                    continue
                try:
                    message = database.get_message_by_frame_id(frame.arbitration_id)
                except KeyError:
                    unknown_ids[frame.arbitration_id] = unknown_ids.get(frame.arbitration_id, 0) + 1
                    continue
                try:
                    decoded = message.decode(bytes(frame.data), decode_choices=False)
                except Exception as error:  # noqa: BLE001 - cantools' DecodeError and others
                    raise LogImportError(
                        path,
                        f"frame {frame_number} (id 0x{frame.arbitration_id:x}): cannot decode "
                        f"{message.name} ({first_line(error)})",
                        column=message.name,
                    ) from None
                for signal, value in decoded.items():
                    unit = message.get_signal_by_name(signal).unit
                    collector.add(f"{message.name}.{signal}", frame.timestamp, float(value), unit)
    except LogImportError:
        raise
    except Exception as error:  # noqa: BLE001 - python-can raises many types for a bad file
        raise LogImportError(path, f"unreadable CAN log ({first_line(error)})") from None
    signals = collector.signals()
    short: dict[str, list[str]] = {}
    for name in signals:
        short.setdefault(name.split(".", 1)[1], []).append(name)
    for name, full in short.items():
        if len(full) == 1 and name not in signals:
            signals[name] = signals[full[0]]
    table = sample_onto_grid(path, signals, requests, mapping, kind="CAN")
    if unknown_ids:
        ids = ", ".join(f"0x{i:x} ({n})" for i, n in sorted(unknown_ids.items()))
        table.notes.append(f"frames with ids the DBC does not know were skipped: {ids}")
    return table
