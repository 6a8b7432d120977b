"""Export a dataset (all or chosen episodes) to one CSV or Parquet table plus a JSON sidecar.

The table has one row per sample, columns in this order::

    episode, step, time_s, <sensor>..., u_<control>..., reward, done

``episode`` is the episode id in the exported dataset, ``time_s`` the time since the
episode start [s], sensors in the dataset's units (``index.json``), controls normalised to
[-1, 1], ``reward`` the row's reward (empty / NaN where unknown), ``done`` the end flag.
The sidecar ``<file>.meta.json`` (e.g. ``demos.csv.meta.json``) holds the dataset's
sensors + units, controls and each exported episode's metadata. Both files are written
atomically.

``mapping_for_export(store)`` is the ``LogMapping`` that imports such a table back
(``import_logs``): the same sensors, actions, times and episode split. ``import_export``
does that and restores the episode metadata from the sidecar.

Command line: ``python -m pilerl.data.export DATASET OUT.csv|OUT.parquet [--episodes 0 3]``;
``--format lerobot`` writes a LeRobot dataset folder instead (``pilerl.data.lerobot``).
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from pilerl.io import atomic_path, write_text_atomic

from .importers import (
    ControlSpec,
    CsvSpec,
    LogMapping,
    MappingError,
    SensorSpec,
    TimeSpec,
    append_episodes,
    check_against_store,
    read_logs,
)
from .schema import SCHEMA_VERSION, EpisodeMeta
from .store import EpisodeStore

FORMATS = {".csv": "csv", ".parquet": "parquet", ".pq": "parquet"}
RESERVED = ("episode", "step", "time_s", "reward", "done")
SIDECAR_SUFFIX = ".meta.json"
EXPORT_FORMAT = "pilerl-export"


def control_column(name: str) -> str:
    """Table column of control ``name``: ``u_<name>``."""
    return f"u_{name}"


def sidecar_path(path: str | Path) -> Path:
    """The metadata sidecar of an exported table: ``<file>.meta.json``."""
    path = Path(path)
    return path.with_name(path.name + SIDECAR_SUFFIX)


def export_columns(store: EpisodeStore) -> list[str]:
    """The table's columns, in order; raises ``ValueError`` if a name would repeat."""
    columns = [
        "episode",
        "step",
        "time_s",
        *store.sensors,
        *(control_column(c) for c in store.controls),
        "reward",
        "done",
    ]
    repeated = sorted({c for c in columns if columns.count(c) > 1})
    if repeated:
        raise ValueError(
            f"{store.root}: sensor / control names clash with export columns "
            f"{repeated}; reserved: {list(RESERVED)}"
        )
    return columns


def episodes_to_frame(
    store: EpisodeStore, *, episode_ids: Sequence[int] | None = None
) -> pd.DataFrame:
    """One row per sample of the chosen episodes (default: all), see the module docstring."""
    columns = export_columns(store)
    ids = list(range(len(store)) if episode_ids is None else episode_ids)
    parts = [_episode_frame(store, i) for i in ids]
    if not parts:
        return pd.DataFrame({c: pd.Series(dtype=_empty_dtype(c)) for c in columns})
    return pd.concat(parts, ignore_index=True)[columns]


def _episode_frame(store: EpisodeStore, episode_id: int) -> pd.DataFrame:
    td = store.load(episode_id)
    n = int(td.batch_size[0])
    data: dict[str, np.ndarray] = {
        "episode": np.full(n, episode_id, dtype=np.int64),
        "step": td["step"].numpy().astype(np.int64),
        "time_s": td["time_s"].numpy().astype(np.float64),
    }
    for name in store.sensors:
        data[name] = td[name].numpy().reshape(n).astype(np.float32)
    actions = td["action"].numpy().reshape(n, -1).astype(np.float32)
    for k, name in enumerate(store.controls):
        data[control_column(name)] = actions[:, k]
    data["reward"] = td["next", "reward"].numpy().reshape(n).astype(np.float32)
    data["done"] = td["next", "done"].numpy().reshape(n).astype(bool)
    return pd.DataFrame(data)


def _empty_dtype(column: str) -> str:
    return {"episode": "int64", "step": "int64", "time_s": "float64", "done": "bool"}.get(
        column, "float32"
    )


def export_episodes(
    store: EpisodeStore,
    path: str | Path,
    *,
    episode_ids: Sequence[int] | None = None,
    format: str | None = None,
) -> Path:
    """Write the chosen episodes (default: all) as one table + the sidecar; returns the table.

    Args:
        store: the dataset.
        path: output file; ``.csv``, ``.parquet`` or ``.pq`` unless ``format`` is given.
        episode_ids: episodes to export, in this order.
        format: ``csv`` or ``parquet``; default from the extension.
    """
    path = Path(path)
    kind = format or FORMATS.get(path.suffix.lower())
    if kind not in ("csv", "parquet"):
        raise ValueError(
            f"{path}: cannot tell the format; use .csv or .parquet or format='csv'/'parquet'"
        )
    ids = list(range(len(store)) if episode_ids is None else episode_ids)
    frame = episodes_to_frame(store, episode_ids=ids)
    with atomic_path(path) as tmp:
        if kind == "csv":
            frame.to_csv(tmp, index=False)
        else:
            frame.to_parquet(tmp, index=False, engine="pyarrow")
    write_text_atomic(sidecar_path(path), json.dumps(_sidecar(store, path, ids, frame), indent=1))
    return path


def export_csv(
    store: EpisodeStore, path: str | Path, *, episode_ids: Sequence[int] | None = None
) -> Path:
    """``export_episodes`` as CSV."""
    return export_episodes(store, path, episode_ids=episode_ids, format="csv")


def export_parquet(
    store: EpisodeStore, path: str | Path, *, episode_ids: Sequence[int] | None = None
) -> Path:
    """``export_episodes`` as Parquet."""
    return export_episodes(store, path, episode_ids=episode_ids, format="parquet")


def _sidecar(store: EpisodeStore, path: Path, ids: Sequence[int], frame: pd.DataFrame) -> dict:
    metas = store.episodes
    return {
        "format": EXPORT_FORMAT,
        "schema_version": SCHEMA_VERSION,
        "table": path.name,
        "dataset": str(store.root),
        "description": store.description,
        "sensors": store.sensors,
        "controls": store.controls,
        "control_columns": {c: control_column(c) for c in store.controls},
        "columns": list(frame.columns),
        "n_rows": len(frame),
        "episodes": [_json_safe(metas[i].to_json()) for i in ids],
    }


def _json_safe(data: dict) -> dict:
    """NaN floats -> None so that the sidecar is strict JSON."""
    return {k: None if isinstance(v, float) and math.isnan(v) else v for k, v in data.items()}


def read_sidecar(path: str | Path) -> dict:
    """The sidecar of an exported table (pass the table's path or the sidecar's)."""
    path = Path(path)
    side = path if path.name.endswith(SIDECAR_SUFFIX) else sidecar_path(path)
    data = json.loads(side.read_text())
    if data.get("format") != EXPORT_FORMAT:
        raise ValueError(f"{side}: not a pilerl export sidecar")
    return data


def mapping_for_export(
    store: EpisodeStore | Mapping,
    *,
    ranges: Mapping[str, Sequence[float]] | None = None,
) -> LogMapping:
    """The ``LogMapping`` that imports a table written by ``export_episodes``.

    Args:
        store: the exported dataset, or a sidecar dict (``read_sidecar``).
        ranges: sensor name -> physical ``[low, high]`` to check on import; sensors not
            given are unbounded (the export came from a validated dataset).
    """
    sensors = store["sensors"] if isinstance(store, Mapping) else store.sensors
    controls = store["controls"] if isinstance(store, Mapping) else store.controls
    ranges = dict(ranges or {})
    unknown = sorted(set(ranges) - set(sensors))
    if unknown:
        raise MappingError(f"ranges: {unknown} are not sensors of the dataset {list(sensors)}")
    return LogMapping(
        sensors={
            name: SensorSpec(
                column=name,
                unit=unit,
                range=[float(x) for x in ranges.get(name, (-math.inf, math.inf))],
            )
            for name, unit in sensors.items()
        },
        controls={name: ControlSpec(column=control_column(name)) for name in controls},
        time=TimeSpec(column="time_s", start_at_zero=False),
        episode_column="episode",
        csv=CsvSpec(delimiter=",", decimal="."),
    )


def import_export(
    path: str | Path,
    store: EpisodeStore,
    *,
    ranges: Mapping[str, Sequence[float]] | None = None,
) -> list[EpisodeMeta]:
    """Import an exported table into ``store``, restoring each episode's metadata from the
    sidecar (source, condition, operator, fill, seed...; ``rate_hz`` too). All-or-nothing,
    like ``import_logs``. Without a sidecar the metadata is what ``import_logs`` makes."""
    path = Path(path)
    side = sidecar_path(path)
    sidecar = read_sidecar(path) if side.exists() else None
    mapping = mapping_for_export(sidecar or store, ranges=ranges)
    check_against_store(mapping, store)
    episodes = read_logs(
        path, mapping, sensor_order=list(store.sensors), control_order=store.controls
    )
    if sidecar is not None:
        by_id = {str(m["id"]): m for m in sidecar["episodes"]}
        for _, meta in episodes:
            label = meta.source.rsplit("#episode=", 1)[-1]
            if label in by_id:
                _restore(meta, by_id[label])
    return append_episodes(store, episodes)


def _restore(meta: EpisodeMeta, saved: dict) -> None:
    restored = EpisodeMeta.from_json(saved)
    for name in (
        "rate_hz",
        "source",
        "condition",
        "condition_params",
        "soil",
        "operator",
        "fill_fraction",
        "success",
        "seed",
        "start",
    ):
        setattr(meta, name, getattr(restored, name))


def main(argv: Sequence[str] | None = None) -> None:
    """``python -m pilerl.data.export DATASET OUT [--episodes ID...]``."""
    parser = argparse.ArgumentParser(description="Export a pilerl dataset to CSV or Parquet.")
    parser.add_argument("dataset", type=Path, help="dataset directory (has index.json)")
    parser.add_argument("out", type=Path, help="output table: .csv or .parquet")
    parser.add_argument("--episodes", type=int, nargs="+", help="episode ids (default: all)")
    parser.add_argument(
        "--format",
        choices=["csv", "parquet", "lerobot"],
        help="default: from OUT's extension; lerobot: a LeRobot v3.0 dataset folder",
    )
    args = parser.parse_args(argv)
    try:
        store = EpisodeStore.open(args.dataset)
        if args.format == "lerobot":
            from .lerobot import export_lerobot

            path = export_lerobot(store, args.out, episode_ids=args.episodes)
            print(f"{path}: LeRobot dataset, {len(args.episodes or range(len(store)))} episodes")
            return
        path = export_episodes(store, args.out, episode_ids=args.episodes, format=args.format)
    except (OSError, ValueError, IndexError) as error:  # SchemaError is a ValueError
        raise SystemExit(f"error: {error}") from None
    print(
        f"{path} (+ {sidecar_path(path).name}): "
        f"{len(args.episodes) if args.episodes else len(store)} episodes"
    )


if __name__ == "__main__":
    main()
