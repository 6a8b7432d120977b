"""ROS 1 bags, ROS 2 bags (sqlite3 or MCAP storage) and MCAP files.

Signals are the numeric fields of each topic's messages, named ``<topic>.<field>``
(``/boom/state.angle``, nested fields joined with dots). A message with a ``header``
counts at its ``header.stamp``, other messages at their log time. MCAP files with JSON
messages are read with ``mcap``; CDR-encoded ROS 2 messages (in ``.mcap``, ``.db3`` or a
bag folder) and ROS 1 ``.bag`` files with ``rosbags``, which decodes them from the
message definitions stored in the file.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from ..errors import LogImportError, first_line
from ..mapping import ColumnRequest, LogMapping
from .base import LogTable
from .optional import require
from .streams import SignalCollector, sample_onto_grid

MCAP_SUFFIXES = (".mcap",)
BAG_SUFFIXES = (".bag", ".db3")


def read_mcap(path: Path, mapping: LogMapping, requests: Sequence[ColumnRequest]) -> LogTable:
    require("mcap", path, "MCAP files")
    from mcap.reader import make_reader

    try:
        with path.open("rb") as stream:
            summary = make_reader(stream).get_summary()
            channels = list(summary.channels.values()) if summary else []
    except Exception as error:  # noqa: BLE001 - mcap raises many types for a bad file
        raise LogImportError(path, f"unreadable MCAP ({first_line(error)})") from None
    encodings = {c.message_encoding for c in channels}
    if encodings and encodings <= {"cdr", "ros1"}:
        return read_bag(path, mapping, requests)
    collector = SignalCollector()
    try:
        with path.open("rb") as stream:
            for _, channel, message in make_reader(stream).iter_messages(log_time_order=True):
                if channel.message_encoding != "json":
                    raise LogImportError(
                        path,
                        f"topic {channel.topic!r}: message encoding "
                        f"{channel.message_encoding!r}; this reader decodes json, and ROS "
                        "(cdr) when every topic is ROS",
                    )
                data = json.loads(message.data)
                collector.add_fields(channel.topic, message.log_time * 1e-9, data)
    except LogImportError:
        raise
    except Exception as error:  # noqa: BLE001
        raise LogImportError(path, f"unreadable MCAP ({first_line(error)})") from None
    return sample_onto_grid(path, collector.signals(), requests, mapping, kind="MCAP")


def read_bag(path: Path, mapping: LogMapping, requests: Sequence[ColumnRequest]) -> LogTable:
    require("rosbags", path, "ROS bags")
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    kind = "ROS 1 bag" if path.suffix == ".bag" else "ROS 2 bag"
    store = Stores.ROS1_NOETIC if path.suffix == ".bag" else Stores.ROS2_HUMBLE
    collector = SignalCollector()
    try:
        with AnyReader([path], default_typestore=get_typestore(store)) as reader:
            for connection, timestamp, rawdata in reader.messages():
                message = reader.deserialize(rawdata, connection.msgtype)
                collector.add_fields(connection.topic, _stamp(message, timestamp), message)
    except Exception as error:  # noqa: BLE001 - rosbags raises many types for a bad file
        raise LogImportError(path, f"unreadable {kind} ({first_line(error)})") from None
    return sample_onto_grid(path, collector.signals(), requests, mapping, kind=kind)


def _stamp(message: object, log_time_ns: int) -> float:
    """Seconds: the message's ``header.stamp`` if it has one, else its log time."""
    stamp = getattr(getattr(message, "header", None), "stamp", None)
    if stamp is not None:
        sec = getattr(stamp, "sec", getattr(stamp, "secs", None))
        nsec = getattr(stamp, "nanosec", getattr(stamp, "nsecs", None))
        if sec is not None and nsec is not None and (sec or nsec):
            return sec + nsec * 1e-9
    return log_time_ns * 1e-9
