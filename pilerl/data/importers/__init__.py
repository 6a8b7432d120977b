"""Import real machine logs into schema-v1 episodes.

A ``LogMapping`` (``mapping``) declares where each pilerl signal is in a log and how to
convert it: source column (and aliases), units (declared, or read from the file: a units
row, ``name [unit]`` headers, MDF / DBC units) converted to the dataset's units, a
calibration ``scale`` / ``offset``, the machine's own sensor ranges, the time base, an
episode column and the episode metadata.

Readers, one per format (``readers``): CSV / TSV as loggers write them (separator and
decimal mark detected or declared, units row, comment lines, ``.gz``, truncation
detected), Parquet, HDF5, and message logs sampled onto a grid: MCAP, ROS 1 / ROS 2 bags,
CAN (BLF / ASC / candump, decoded with a DBC file), MDF 4. The message-log readers need
the optional extra ``pip install 'pilerl[logs]'``.

``import_logs(paths, mapping, store)`` reads every file, validates *all* episodes of *all*
files, and only then appends them to the ``EpisodeStore`` (a bad file leaves the store as
it was); it then stores the normalisation statistics and a provenance record
(``dataset``). ``quality_report`` measures rate, gaps, jitter, frozen / clipped sensors,
ranges and the single-control share, and plots every episode (``quality``).

Every problem in a log is a ``LogImportError`` (a ``SchemaError``) whose message names
the file, the column and the row, rows counted as *1-based data rows* (the first row
after a CSV header, or after its units row, is row 1; in Parquet / HDF5 row 1 is index
0; text formats add the file's line). The message reports the first bad row of the first
bad column, columns checked in the order: episode, time, sensors, controls, metadata
columns. A malformed mapping is a ``MappingError``.

Command line: ``python -m pilerl.data.importers --mapping m.yaml --dataset DIR LOG...``.
"""

from __future__ import annotations

from .columns import CONTROL_TOLERANCE, FALSE_WORDS, TRUE_WORDS
from .dataset import (
    append_episodes,
    create_store,
    file_digest,
    finish_import,
    import_episodes,
    import_logs,
    import_new_dataset,
    import_to_dataset,
    machine_ranges,
    quality_dir,
    read_provenance,
)
from .episodes import ImportedEpisode, read_all, read_episodes, read_log_episodes, read_logs
from .errors import ROWS, LogImportError, MappingError
from .mapping import (
    CanSpec,
    ColumnRequest,
    ControlSpec,
    CsvSpec,
    LogMapping,
    MetadataSpec,
    SensorSpec,
    TimeSpec,
    check_against_store,
    check_mapping,
    load_mapping,
    mapping_from_dict,
    mapping_to_dict,
    save_mapping,
)
from .quality import QualityReport, quality_report
from .readers import LogTable, known_suffixes, read_log

__all__ = [
    "CONTROL_TOLERANCE",
    "FALSE_WORDS",
    "ROWS",
    "TRUE_WORDS",
    "CanSpec",
    "ColumnRequest",
    "ControlSpec",
    "CsvSpec",
    "ImportedEpisode",
    "LogImportError",
    "LogMapping",
    "LogTable",
    "MappingError",
    "MetadataSpec",
    "QualityReport",
    "SensorSpec",
    "TimeSpec",
    "append_episodes",
    "check_against_store",
    "check_mapping",
    "create_store",
    "file_digest",
    "finish_import",
    "import_episodes",
    "import_logs",
    "import_new_dataset",
    "import_to_dataset",
    "known_suffixes",
    "load_mapping",
    "machine_ranges",
    "mapping_from_dict",
    "mapping_to_dict",
    "quality_dir",
    "quality_report",
    "read_all",
    "read_episodes",
    "read_log",
    "read_log_episodes",
    "read_logs",
    "read_provenance",
    "save_mapping",
]
