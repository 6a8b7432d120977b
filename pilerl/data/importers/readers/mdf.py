"""ASAM MDF 4 (and 3) measurement files, read with ``asammdf``.

Every numeric channel is a signal named as in the file, with the file's unit and its
own time base (the group's master channel).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import LogImportError, first_line
from ..mapping import ColumnRequest, LogMapping
from .base import LogTable
from .optional import require
from .streams import Signal, sample_onto_grid

MDF_SUFFIXES = (".mf4", ".mdf", ".dat")


def read_mdf(path: Path, mapping: LogMapping, requests: Sequence[ColumnRequest]) -> LogTable:
    require("asammdf", path, "MDF files")
    from asammdf import MDF

    signals: dict[str, Signal] = {}
    try:
        with MDF(path) as mdf:
            for signal in mdf.iter_channels(copy_master=True):
                samples = np.asarray(signal.samples)
                if samples.ndim != 1 or samples.dtype.kind not in "biuf":
                    continue
                if signal.name in signals:
                    continue  # the same name in two groups: the first one counts
                signals[signal.name] = Signal(
                    np.asarray(signal.timestamps, dtype=np.float64),
                    samples.astype(np.float64),
                    signal.unit or None,
                )
    except Exception as error:  # noqa: BLE001 - asammdf raises many types for a bad file
        raise LogImportError(path, f"unreadable MDF ({first_line(error)})") from None
    return sample_onto_grid(path, signals, requests, mapping, kind="MDF")
