"""Importing into a dataset: all or nothing, then statistics and a provenance record.

``import_logs`` reads and checks every episode of every file before the first one is
written, appends them in one atomic ``EpisodeStore.extend``, and then stores the
normalisation statistics (``pilerl.data.curation.compute_stats``, as ``build_dataset``
does) so that the dataset is ready to train. ``import_new_dataset`` builds a new
dataset in a hidden folder beside the target and renames it into place at the end, so a
failure or a kill leaves no half-made dataset.

Each import appends a record to ``imports.json`` in the dataset folder: when, which
files (path, size, SHA-256, episode ids), the mapping, and the machine's own sensor
ranges (the mapping's, which the imported data was checked against).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import math
import os
import shutil
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from pilerl.data.curation import compute_stats
from pilerl.data.schema import EpisodeMeta, SchemaError
from pilerl.data.store import EpisodeStore
from pilerl.io import write_text_atomic

from .episodes import ImportedEpisode, as_paths, read_all
from .mapping import LogMapping, check_against_store, load_mapping, mapping_to_dict

PROVENANCE = "imports.json"
PROVENANCE_FORMAT = "pilerl-imports"


def create_store(
    root: str | Path, mapping: LogMapping, *, description: str = "", exist_ok: bool = False
) -> EpisodeStore:
    """A new dataset with the mapping's sensors (and units) and controls, in mapping order."""
    return EpisodeStore.create(
        root,
        sensors={name: spec.unit for name, spec in mapping.sensors.items()},
        controls=list(mapping.controls),
        description=description,
        exist_ok=exist_ok,
    )


def append_episodes(
    store: EpisodeStore, episodes: Iterable[tuple] | Iterable[ImportedEpisode]
) -> list[EpisodeMeta]:
    """Append already-validated episodes to ``store`` as one atomic change."""
    pairs = [e.pair() if isinstance(e, ImportedEpisode) else e for e in episodes]
    return store.extend(pairs)


def import_logs(
    paths: str | Path | Iterable[str | Path],
    mapping: LogMapping | Mapping | str | Path,
    store: EpisodeStore,
) -> list[EpisodeMeta]:
    """Import log files into ``store``: all-or-nothing over the files.

    Every episode of every file is read and validated first (a ``LogImportError`` /
    ``MappingError`` leaves the store untouched); only then are they appended, in file
    order, and the statistics and provenance updated. Returns the stored metadata (ids
    set). All episodes are held in memory until appended.
    """
    return import_episodes(paths, mapping, store)[1]


def import_episodes(
    paths: str | Path | Iterable[str | Path],
    mapping: LogMapping | Mapping | str | Path,
    store: EpisodeStore,
) -> tuple[list[ImportedEpisode], list[EpisodeMeta]]:
    """``import_logs`` that also returns the read episodes (for the quality report)."""
    mapping = load_mapping(mapping)
    check_against_store(mapping, store)
    paths = as_paths(paths)
    episodes = read_all(
        paths, mapping, sensor_order=list(store.sensors), control_order=store.controls
    )
    metas = append_episodes(store, episodes)
    if metas:
        finish_import(store, mapping, paths, episodes)
    return episodes, metas


def import_new_dataset(
    paths: str | Path | Iterable[str | Path],
    mapping: LogMapping | Mapping | str | Path,
    root: str | Path,
    *,
    description: str = "",
) -> tuple[EpisodeStore, list[ImportedEpisode]]:
    """A new dataset at ``root`` from the logs: built in a hidden folder beside it and
    renamed into place only when complete. ``root`` must not hold a dataset."""
    mapping = load_mapping(mapping)
    root = Path(root)
    if root.exists() and (not root.is_dir() or any(root.iterdir())):
        raise FileExistsError(f"{root}: exists and is not an empty folder")
    paths = as_paths(paths)
    episodes = read_all(paths, mapping)  # every check before anything is written
    root.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{root.name}.importing-", dir=root.parent))
    try:
        store = create_store(tmp, mapping, description=description)
        append_episodes(store, episodes)
        finish_import(store, mapping, paths, episodes)
        if root.exists():
            root.rmdir()  # empty (checked above)
        os.rename(tmp, root)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return EpisodeStore.open(root), episodes


def import_to_dataset(
    paths: str | Path | Iterable[str | Path],
    mapping: LogMapping | Mapping | str | Path,
    root: str | Path,
    *,
    description: str = "",
) -> tuple[EpisodeStore, list[ImportedEpisode], list[EpisodeMeta]]:
    """Import logs into the dataset at ``root``: appended when a dataset is there
    (``import_episodes``), else a new one built from the mapping (``import_new_dataset``;
    ``description`` names it). All or nothing either way. Returns the dataset, the read
    episodes (for the quality report) and the metadata of the imported ones."""
    mapping = load_mapping(mapping)
    root = Path(root)
    if (root / "index.json").exists() or (root.is_dir() and any(root.iterdir())):
        store = _open_for_import(root)
        episodes, metas = import_episodes(paths, mapping, store)
        return store, episodes, metas
    store, episodes = import_new_dataset(paths, mapping, root, description=description)
    return store, episodes, [e.meta for e in episodes]


def quality_dir(root: str | Path) -> Path:
    """Where the quality report of the dataset's latest import goes:
    ``root/quality/import_<k>`` with k the import's number (000 first)."""
    return Path(root) / "quality" / f"import_{len(read_provenance(root)) - 1:03d}"


def _open_for_import(root: Path) -> EpisodeStore:
    """An existing dataset opened for writing; a broken one is an error naming it."""
    try:
        return EpisodeStore.open(root, writable=True)
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:
        raise SchemaError(
            f"{root}: not a usable pilerl dataset ({type(error).__name__}: {error})"
        ) from None


def finish_import(
    store: EpisodeStore,
    mapping: LogMapping,
    paths: Sequence[Path],
    episodes: Sequence[ImportedEpisode],
) -> None:
    """Statistics over the whole dataset, and the provenance record of this import."""
    store.set_stats(compute_stats(store))
    ids_by_file: dict[Path, list[int]] = {}
    for episode in episodes:
        ids_by_file.setdefault(episode.file, []).append(episode.meta.id)
    record = {
        "imported_at": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "episodes": [e.meta.id for e in episodes],
        "files": [
            {
                "path": str(path.resolve()),
                "bytes": _size(path),
                "sha256": file_digest(path),
                "episodes": ids_by_file.get(path, []),
            }
            for path in paths
        ],
        "mapping": _json_safe(mapping_to_dict(mapping)),
        "sensor_ranges": {
            name: {"low": _finite(spec.range[0]), "high": _finite(spec.range[1]), "unit": spec.unit}
            for name, spec in mapping.sensors.items()
        },
    }
    history = read_provenance(store.root)
    history.append(record)
    text = json.dumps({"format": PROVENANCE_FORMAT, "imports": history}, indent=1, allow_nan=False)
    write_text_atomic(store.root / PROVENANCE, text)


def read_provenance(root: str | Path) -> list[dict]:
    """The import records of a dataset (empty if it has none)."""
    path = Path(root) / PROVENANCE
    if not path.exists():
        return []
    data = json.loads(path.read_text())
    return list(data.get("imports", []))


def machine_ranges(root: str | Path) -> dict[str, tuple[float, float]]:
    """Sensor name -> the machine's range ``(low, high)`` from the latest import record."""
    history = read_provenance(root)
    if not history:
        return {}
    ranges = history[-1]["sensor_ranges"]
    return {
        name: (
            -math.inf if r["low"] is None else r["low"],
            math.inf if r["high"] is None else r["high"],
        )
        for name, r in ranges.items()
    }


def file_digest(path: Path) -> str:
    """SHA-256 of a file, or of every file of a folder (ROS 2 bag) in name order."""
    digest = hashlib.sha256()
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for file in files:
        if path.is_dir():
            digest.update(str(file.relative_to(path)).encode())
        with file.open("rb") as stream:
            for block in iter(lambda: stream.read(1 << 20), b""):  # noqa: B023
                digest.update(block)
    return digest.hexdigest()


def _size(path: Path) -> int:
    if path.is_dir():
        return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
    return path.stat().st_size


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _json_safe(value: object) -> object:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value
