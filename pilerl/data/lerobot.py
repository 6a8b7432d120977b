"""Move demonstrations between pilerl datasets and the LeRobot dataset layout (v3.0).

``export_lerobot(store, out)`` writes the layout that LeRobot and TorchRL's
``LeRobotExperienceReplay`` read (``torchrl/data/datasets/lerobot.py``)::

    out/meta/info.json                          codebase_version "v3.0", fps, features
    out/meta/stats.json                         mean / std / min / max per feature
    out/meta/tasks.parquet                      task_index, task
    out/meta/episodes/chunk-000/file-000.parquet    one row per episode
    out/data/chunk-000/file-000.parquet         one row per frame

Frames carry ``observation.state`` (the sensors, in the dataset's units, in order),
``action`` (controls in [-1, 1]), ``timestamp`` (s since the episode start),
``frame_index``, ``episode_index``, ``index``, ``task_index``, ``next.reward`` and
``next.done``. The task of an episode is its condition. pilerl's own words ride along:
``info.json`` holds ``pilerl`` (schema version, sensors + units, controls) and each
episode row a ``pilerl_meta`` JSON text with the full ``EpisodeMeta``, so an export
imports back with its metadata. LeRobot datasets have one frame rate: episodes recorded
at different rates are refused (curate with ``build_dataset(rate_hz=...)`` first). The
folder is built beside ``out`` and renamed into place when complete.

``import_lerobot(root, store)`` reads such a folder (ours, or one made by LeRobot with
a numeric ``observation.state``; then ``sensor_units`` names each state component's
unit) into an ``EpisodeStore``: ``next`` readings are the following frame's (the last
frame repeats its own), rewards and end flags come from ``next.reward`` / ``next.done``
where present. Nothing downloads.

Command line: ``python -m pilerl.data.lerobot export DATASET OUT [--episodes ...]`` and
``python -m pilerl.data.lerobot import LEROBOT_DIR DATASET`` (``import_lerobot_dataset``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import torch

from .curation import compute_stats
from .schema import SCHEMA_VERSION, EpisodeMeta, SchemaError, make_episode, validate_episode
from .store import EpisodeStore

CODEBASE_VERSION = "v3.0"
ROBOT_TYPE = "wheel_loader"
DATA_FILE = Path("data/chunk-000/file-000.parquet")
EPISODES_FILE = Path("meta/episodes/chunk-000/file-000.parquet")
CHUNKS_SIZE = 1000


class LeRobotFormatError(SchemaError):
    """A folder is not a LeRobot dataset this reader understands; names the file and field."""


# ---------------------------------------------------------------------------- export
def export_lerobot(
    store: EpisodeStore, out: str | Path, *, episode_ids: Sequence[int] | None = None
) -> Path:
    """Write the chosen episodes (default: all) as a LeRobot v3.0 dataset folder ``out``."""
    out = Path(out)
    if out.exists():
        raise FileExistsError(f"{out}: exists; choose a new folder")
    ids = list(range(len(store)) if episode_ids is None else episode_ids)
    if not ids:
        raise ValueError(f"{store.root}: no episodes to export")
    metas = store.episodes
    rates = sorted({metas[i].rate_hz for i in ids})
    if len(rates) > 1:
        raise ValueError(
            f"{store.root}: episodes at {rates} Hz; a LeRobot dataset has one fps: "
            "curate to one rate first (build_dataset rate_hz=...)"
        )
    tasks = list(dict.fromkeys(metas[i].condition for i in ids))
    frames, episodes = _frames_and_episodes(store, ids, tasks)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.exporting-", dir=out.parent))
    try:
        for path in (tmp / DATA_FILE, tmp / EPISODES_FILE):
            path.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(frames, tmp / DATA_FILE)
        pq.write_table(episodes, tmp / EPISODES_FILE)
        pq.write_table(
            pa.table({"task_index": pa.array(range(len(tasks)), pa.int64()), "task": tasks}),
            tmp / "meta" / "tasks.parquet",
        )
        info = _info(store, rates[0], frames.num_rows, len(ids), len(tasks))
        (tmp / "meta" / "info.json").write_text(json.dumps(info, indent=2))
        (tmp / "meta" / "stats.json").write_text(json.dumps(_stats(frames), indent=2))
        os.rename(tmp, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out


def _frames_and_episodes(
    store: EpisodeStore, ids: Sequence[int], tasks: list[str]
) -> tuple[pa.Table, pa.Table]:
    metas = store.episodes
    columns: dict[str, list] = {
        "observation.state": [],
        "action": [],
        "timestamp": [],
        "frame_index": [],
        "episode_index": [],
        "index": [],
        "task_index": [],
        "next.reward": [],
        "next.done": [],
    }
    rows: dict[str, list] = {
        "episode_index": [],
        "length": [],
        "dataset_from_index": [],
        "dataset_to_index": [],
        "tasks": [],
        "data/chunk_index": [],
        "data/file_index": [],
        "pilerl_meta": [],
    }
    start = 0
    for new_id, episode_id in enumerate(ids):
        td = store.load(episode_id)
        n = int(td.batch_size[0])
        state = np.concatenate([td[s].numpy().reshape(n, 1) for s in store.sensors], axis=1)
        columns["observation.state"].append(state.astype(np.float32))
        columns["action"].append(td["action"].numpy().reshape(n, -1).astype(np.float32))
        time_s = td["time_s"].numpy()
        columns["timestamp"].append((time_s - time_s[0]).astype(np.float32))
        columns["frame_index"].append(np.arange(n, dtype=np.int64))
        columns["episode_index"].append(np.full(n, new_id, dtype=np.int64))
        columns["index"].append(np.arange(start, start + n, dtype=np.int64))
        task = tasks.index(metas[episode_id].condition)
        columns["task_index"].append(np.full(n, task, dtype=np.int64))
        columns["next.reward"].append(td["next", "reward"].numpy().reshape(n).astype(np.float32))
        columns["next.done"].append(td["next", "done"].numpy().reshape(n).astype(bool))
        meta = metas[episode_id].to_json()
        rows["episode_index"].append(new_id)
        rows["length"].append(n)
        rows["dataset_from_index"].append(start)
        rows["dataset_to_index"].append(start + n)
        rows["tasks"].append([tasks[task]])
        rows["data/chunk_index"].append(0)
        rows["data/file_index"].append(0)
        rows["pilerl_meta"].append(json.dumps(meta, allow_nan=False))
        start += n
    frames = {}
    for name, parts in columns.items():
        values = np.concatenate(parts)
        if values.ndim == 2:  # fixed-size vectors, as LeRobot stores them
            frames[name] = pa.FixedSizeListArray.from_arrays(
                pa.array(values.reshape(-1)), values.shape[1]
            )
        else:
            frames[name] = pa.array(values)
    return pa.table(frames), pa.table(rows)


def _info(store: EpisodeStore, fps: float, n_frames: int, n_episodes: int, n_tasks: int) -> dict:
    sensors, controls = list(store.sensors), store.controls
    scalar = {"shape": [1], "names": None}
    return {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": ROBOT_TYPE,
        "total_episodes": n_episodes,
        "total_frames": n_frames,
        "total_tasks": n_tasks,
        "chunks_size": CHUNKS_SIZE,
        "fps": fps,
        "splits": {"train": f"0:{n_episodes}"},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": None,
        "features": {
            "observation.state": {"dtype": "float32", "shape": [len(sensors)], "names": sensors},
            "action": {"dtype": "float32", "shape": [len(controls)], "names": controls},
            "timestamp": {"dtype": "float32", **scalar},
            "frame_index": {"dtype": "int64", **scalar},
            "episode_index": {"dtype": "int64", **scalar},
            "index": {"dtype": "int64", **scalar},
            "task_index": {"dtype": "int64", **scalar},
            "next.reward": {"dtype": "float32", **scalar},
            "next.done": {"dtype": "bool", **scalar},
        },
        "pilerl": {
            "schema_version": SCHEMA_VERSION,
            "sensors": store.sensors,
            "controls": controls,
        },
    }


def _stats(frames: pa.Table) -> dict:
    out = {}
    for name in ("observation.state", "action"):
        values = _matrix(frames.column(name))
        out[name] = {
            "mean": values.mean(0).tolist(),
            "std": values.std(0).tolist(),
            "min": values.min(0).tolist(),
            "max": values.max(0).tolist(),
        }
    return out


def _matrix(column: pa.ChunkedArray) -> np.ndarray:
    """A list-typed column as a float64 matrix [rows, width]."""
    return np.asarray(column.to_pylist(), dtype=np.float64)


# ---------------------------------------------------------------------------- import
def read_lerobot(
    root: str | Path, *, sensor_units: Mapping[str, str] | None = None
) -> tuple[dict[str, str], list[str], list[tuple]]:
    """``(sensors {name: unit}, controls, [(episode, meta), ...])`` of a LeRobot folder."""
    root = Path(root)
    info = _read_info(root)
    features = info.get("features", {})
    for key in ("observation.state", "action"):
        if key not in features:
            raise LeRobotFormatError(f"{root / 'meta/info.json'}: features has no {key!r}")
    state_names = _names(root, features["observation.state"], "observation.state")
    controls = _names(root, features["action"], "action")
    declared = info.get("pilerl", {}).get("sensors") or dict(sensor_units or {})
    missing = [n for n in state_names if n not in declared]
    if missing:
        raise LeRobotFormatError(
            f"{root}: no unit for observation.state components {missing}; pass sensor_units"
        )
    sensors = {name: declared[name] for name in state_names}
    fps = float(info["fps"])
    table = _read_frames(root)
    for column in ("observation.state", "action", "episode_index"):
        if column not in table.column_names:
            raise LeRobotFormatError(f"{root / 'data'}: no column {column!r}")
    state = _matrix(table.column("observation.state"))
    action = _matrix(table.column("action"))
    if state.shape[1] != len(sensors) or action.shape[1] != len(controls):
        raise LeRobotFormatError(
            f"{root}: observation.state has {state.shape[1]} components and action "
            f"{action.shape[1]}; info.json names {len(sensors)} and {len(controls)}"
        )
    episode_index = table.column("episode_index").to_numpy()
    time_s = (
        table.column("timestamp").to_numpy().astype(np.float64)
        if "timestamp" in table.column_names
        else None
    )
    reward = _optional(table, "next.reward", np.float32)
    done = _optional(table, "next.done", bool)
    metas = _episode_metas(root)
    tasks = _tasks(root)
    task_index = _optional(table, "task_index", np.int64)
    out = []
    for label in dict.fromkeys(episode_index.tolist()):
        rows = np.flatnonzero(episode_index == label)
        if np.any(np.diff(rows) != 1):
            raise LeRobotFormatError(f"{root}: frames of episode {label} are not contiguous")
        n = len(rows)
        times = time_s[rows] if time_s is not None else np.arange(n) / fps
        readings = {
            name: torch.from_numpy(state[rows, k].astype(np.float32))
            for k, name in enumerate(sensors)
        }
        following = {k: torch.cat([v[1:], v[-1:]]) for k, v in readings.items()}
        ended = bool(done[rows][-1]) if done is not None else True
        episode = make_episode(
            sensors=readings,
            next_sensors=following,
            actions=torch.from_numpy(action[rows].astype(np.float32)),
            time_s=torch.from_numpy(times - times[0]),
            rewards=None if reward is None else torch.from_numpy(reward[rows]),
            terminated=ended,
            truncated=not ended,
        )
        meta = metas.get(int(label))
        if meta is None:
            task = tasks.get(int(task_index[rows][0])) if task_index is not None else None
            meta = EpisodeMeta(
                rate_hz=fps,
                source=f"lerobot:{root}#episode={label}",
                condition=task or "unknown",
            )
        out.append((episode, meta))
    return sensors, controls, out


def import_lerobot(
    root: str | Path,
    store: EpisodeStore,
    *,
    sensor_units: Mapping[str, str] | None = None,
) -> list[EpisodeMeta]:
    """Append every episode of a LeRobot folder to ``store`` (one atomic change); the
    store's sensors (with units) and controls must match the folder's."""
    sensors, controls, episodes = read_lerobot(root, sensor_units=sensor_units)
    return _append(root, store, sensors, controls, episodes)


def import_lerobot_dataset(
    root: str | Path,
    dataset: str | Path,
    *,
    sensor_units: Mapping[str, str] | None = None,
) -> tuple[EpisodeStore, list[EpisodeMeta]]:
    """Import a LeRobot folder into the pilerl dataset at ``dataset``, created with the
    folder's sensors and controls when it does not exist. Every episode is checked before
    the dataset is created or changed, so a bad folder leaves nothing behind."""
    sensors, controls, episodes = read_lerobot(root, sensor_units=sensor_units)
    for k, (episode, _) in enumerate(episodes):
        validate_episode(
            episode, list(sensors), action_dim=len(controls), where=f"{root} episode {k}"
        )
    store = EpisodeStore.create(dataset, sensors=sensors, controls=controls, exist_ok=True)
    return store, _append(root, store, sensors, controls, episodes)


def _append(
    root: str | Path,
    store: EpisodeStore,
    sensors: dict[str, str],
    controls: list[str],
    episodes: list[tuple],
) -> list[EpisodeMeta]:
    if sensors != store.sensors or controls != store.controls:
        raise LeRobotFormatError(
            f"{root}: sensors {sensors} and controls {controls}; the dataset {store.root} has "
            f"{store.sensors} and {store.controls}"
        )
    metas = store.extend(episodes)
    store.set_stats(compute_stats(store))
    return metas


def _read_info(root: Path) -> dict:
    path = root / "meta" / "info.json"
    try:
        info = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as error:
        raise LeRobotFormatError(f"{path}: cannot read ({error})") from None
    if not isinstance(info, dict) or "fps" not in info:
        raise LeRobotFormatError(f"{path}: not a LeRobot info.json (no 'fps')")
    version = str(info.get("codebase_version", "")).lstrip("v")
    if version.split(".")[0] not in ("2", "3"):
        raise LeRobotFormatError(
            f"{path}: codebase_version {info.get('codebase_version')!r}; "
            "this reader knows v2.x and v3.x"
        )
    fps = info["fps"]
    if not isinstance(fps, int | float) or not math.isfinite(fps) or fps <= 0:
        raise LeRobotFormatError(f"{path}: fps must be > 0, got {fps!r}")
    return info


def _names(root: Path, feature: Mapping, key: str) -> list[str]:
    names = feature.get("names")
    if isinstance(names, Mapping):  # LeRobot also writes {"motors": [...]}
        names = next(iter(names.values()), None)
    shape = feature.get("shape", [])
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        width = shape[0] if shape else 0
        names = [f"{key.split('.')[-1]}_{i}" for i in range(width)]
    if shape and shape[0] != len(names):
        raise LeRobotFormatError(
            f"{root / 'meta/info.json'}: {key} shape {shape} but {len(names)} names"
        )
    return names


def _read_frames(root: Path) -> pa.Table:
    files = sorted((root / "data").rglob("*.parquet"))
    if not files:
        raise LeRobotFormatError(f"{root / 'data'}: no parquet files")
    try:
        table = pa.concat_tables([pq.read_table(f) for f in files])
    except (pa.ArrowException, OSError) as error:
        raise LeRobotFormatError(f"{root / 'data'}: unreadable parquet ({error})") from None
    if "index" in table.column_names:
        table = table.sort_by("index")
    return table


def _optional(table: pa.Table, column: str, dtype) -> np.ndarray | None:  # noqa: ANN001
    if column not in table.column_names:
        return None
    return table.column(column).to_numpy().astype(dtype)


def _episode_metas(root: Path) -> dict[int, EpisodeMeta]:
    folder = root / "meta" / "episodes"
    out: dict[int, EpisodeMeta] = {}
    for file in sorted(folder.rglob("*.parquet")) if folder.exists() else []:
        for row in pq.read_table(file).to_pylist():
            if row.get("pilerl_meta"):
                data = json.loads(row["pilerl_meta"])
                data.pop("id", None)
                data.pop("n_samples", None)
                out[int(row["episode_index"])] = EpisodeMeta.from_json(data)
    return out


def _tasks(root: Path) -> dict[int, str]:
    path = root / "meta" / "tasks.parquet"
    if not path.exists():
        return {}
    out = {}
    for row in pq.read_table(path).to_pylist():
        text = row.get("task", row.get("__index_level_0__"))
        if row.get("task_index") is not None and isinstance(text, str):
            out[int(row["task_index"])] = text
    return out


# ---------------------------------------------------------------------------- CLI
def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m pilerl.data.lerobot", description="LeRobot dataset export / import."
    )
    commands = parser.add_subparsers(dest="command", required=True)
    export = commands.add_parser("export", help="pilerl dataset -> LeRobot folder")
    export.add_argument("dataset", type=Path)
    export.add_argument("out", type=Path)
    export.add_argument("--episodes", type=int, nargs="+")
    imp = commands.add_parser("import", help="LeRobot folder -> pilerl dataset")
    imp.add_argument("lerobot", type=Path)
    imp.add_argument("dataset", type=Path, help="created when it does not exist")
    args = parser.parse_args(argv)
    try:
        if args.command == "export":
            store = EpisodeStore.open(args.dataset)
            path = export_lerobot(store, args.out, episode_ids=args.episodes)
            count = len(args.episodes) if args.episodes else len(store)
            print(f"{path}: {count} episodes (LeRobot {CODEBASE_VERSION})")
        else:
            store, metas = import_lerobot_dataset(args.lerobot, args.dataset)
            print(f"{args.dataset}: imported {len(metas)} episodes; {len(store)} in the dataset")
    except (OSError, ValueError, IndexError, KeyError) as error:  # SchemaError is a ValueError
        raise SystemExit(f"error: {error}") from None


if __name__ == "__main__":
    main()
