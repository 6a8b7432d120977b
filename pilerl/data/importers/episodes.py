"""From a log's table to schema-v1 episodes, and into a dataset (all or nothing).

Per file (or per episode-column run):

* ``<sensor>`` at row i is the converted reading at row i, ``("next", <sensor>)`` the
  reading at row i + 1. The last row has no later reading, so its ``next`` repeats its own
  reading and the row is flagged ``done`` and ``terminated`` (the demonstration ended
  there: nothing to bootstrap beyond it), ``truncated`` stays False.
* ``time_s`` is the converted time minus the episode's first time (``time.start_at_zero:
  false`` keeps the log's times); ``rate_hz`` in the metadata is ``time.resample_hz``, else
  ``time.rate_hz``, else 1 / median sample interval.
* rewards are NaN (unknown).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from tensordict import TensorDict

from pilerl.data.schema import EpisodeMeta, make_episode, validate_episode

from .columns import control_values, fill_fractions, label, sensor_values, successes
from .mapping import LogMapping, MetadataSpec, load_mapping
from .readers import LogTable, read_log
from .timing import Sampling, check_increasing, parse_times, resample, sampling


@dataclass
class ImportedEpisode:
    """One episode read from a log, with what the quality report needs.

    Attributes:
        episode: the schema-v1 TensorDict.
        meta: its metadata (id unset until stored).
        file: the log file.
        label: the episode column's value ('' when one file is one episode).
        first_row: 1-based data row of the episode's first row in the file.
        sampling: rate, jitter and gaps as logged.
        notes: what the reader did (separator detected, signals resampled...).
        signal_gaps: message logs: longest interval between two messages per column [s].
    """

    episode: TensorDict
    meta: EpisodeMeta
    file: Path
    label: str
    first_row: int
    sampling: Sampling
    notes: list[str] = field(default_factory=list)
    signal_gaps: dict[str, float] = field(default_factory=dict)

    def pair(self) -> tuple[TensorDict, EpisodeMeta]:
        return self.episode, self.meta


def segments(table: LogTable, column: str | None) -> list[tuple[str, int, int]]:
    """(episode label, first row index, end row index) for each episode of a file."""
    n = len(table)
    if column is None:
        return [("", 0, n)]
    series = table.frame[column]
    missing = series.isna().to_numpy() | series.astype(str).str.strip().eq("").to_numpy()
    if missing.any():
        raise table.error("missing episode id", column=column, row=int(np.argmax(missing)) + 1)
    labels = [label(v) for v in series.tolist()]
    starts = [0] + [i for i in range(1, n) if labels[i] != labels[i - 1]]
    seen: set[str] = set()
    for start in starts:
        if labels[start] in seen:
            raise table.error(
                f"episode {labels[start]!r} appears again after other "
                "episodes; the rows of one episode must be contiguous",
                column=column,
                row=start + 1,
            )
        seen.add(labels[start])
    ends = [*starts[1:], n]
    return [(labels[s], s, e) for s, e in zip(starts, ends, strict=True)]


def _times(
    table: LogTable, mapping: LogMapping, parts: Sequence[tuple[str, int, int]]
) -> np.ndarray:
    """Absolute time [s] of every row, strictly increasing within each episode."""
    spec = mapping.time
    if spec.column is None:
        times = np.empty(len(table))
        for _, start, end in parts:
            times[start:end] = np.arange(end - start) / spec.rate_hz
        return times
    times = parse_times(table, spec)
    check_increasing(table, mapping, times, parts)
    return times


def _fill_per_row(table: LogTable, spec: MetadataSpec) -> np.ndarray:
    """Fill fraction at every row (NaN = unknown): the column, or the fixed value."""
    if spec.fill_fraction_column is not None:
        return fill_fractions(table, spec.fill_fraction_column)
    value = math.nan if spec.fill_fraction is None else spec.fill_fraction
    return np.full(len(table), value)


def _success_per_row(table: LogTable, spec: MetadataSpec) -> list[bool | None]:
    """Half-full outcome at every row (None = unknown): the column, or the fixed value."""
    if spec.success_column is not None:
        return successes(table, spec.success_column)
    return [spec.success] * len(table)


def _episode(
    sensors: Mapping[str, np.ndarray], actions: np.ndarray, time_s: np.ndarray
) -> TensorDict:
    """A schema-v1 episode; ``next`` is the following row, the last row repeats itself."""
    current = {k: torch.from_numpy(v.astype(np.float32)) for k, v in sensors.items()}
    following = {k: torch.cat([v[1:], v[-1:]]) for k, v in current.items()}
    return make_episode(
        sensors=current,
        next_sensors=following,
        actions=torch.from_numpy(actions.astype(np.float32)),
        time_s=torch.from_numpy(np.ascontiguousarray(time_s, dtype=np.float64)),
        terminated=True,
    )


def _rate_hz(table: LogTable, mapping: LogMapping, time_s: np.ndarray, episode: str) -> float:
    if mapping.time.resample_hz is not None:
        return float(mapping.time.resample_hz)
    if mapping.time.rate_hz is not None:
        return float(mapping.time.rate_hz)
    if len(time_s) < 2:
        where = f" (episode {episode!r})" if episode else ""
        raise table.error(
            f"one row{where}: cannot estimate the sampling rate; set time.rate_hz in the mapping",
            column=mapping.time.column,
        )
    return float(f"{1.0 / float(np.median(np.diff(time_s))):.9g}")


def _meta(
    path: Path, mapping: LogMapping, episode: str, rate_hz: float, fill: float, success: bool | None
) -> EpisodeMeta:
    spec = mapping.metadata
    return EpisodeMeta(
        rate_hz=rate_hz,
        source=f"import:{path}" + (f"#episode={episode}" if episode else ""),
        condition=spec.condition,
        condition_params=dict(spec.condition_params),
        operator={"id": spec.operator_id, "kind": spec.operator_kind},
        fill_fraction=fill,
        success=success,
    )


def read_log_episodes(
    path: str | Path,
    mapping: LogMapping,
    *,
    sensor_order: Sequence[str] | None = None,
    control_order: Sequence[str] | None = None,
) -> list[ImportedEpisode]:
    """Read, check and convert one log file into episodes (nothing is written)."""
    path = Path(path)
    sensor_order = list(sensor_order or mapping.sensors)
    control_order = list(control_order or mapping.controls)
    table = read_log(path, mapping)
    parts = segments(table, mapping.episode_column)
    times = _times(table, mapping, parts)
    sensors = {n: sensor_values(table, n, mapping.sensors[n]) for n in sensor_order}
    actions = (
        np.stack([control_values(table, n, mapping.controls[n]) for n in control_order], axis=-1)
        if control_order
        else np.zeros((len(table), 0))
    )
    fills = _fill_per_row(table, mapping.metadata)
    outcomes = _success_per_row(table, mapping.metadata)
    episodes = []
    for episode_label, start, end in parts:
        rows = slice(start, end)
        rate = _rate_hz(table, mapping, times[rows], episode_label)
        logged = sampling(times[rows], mapping.time.rate_hz, first_row=start + 1)
        episode_times = times[rows]
        episode_sensors = {n: v[rows] for n, v in sensors.items()}
        episode_actions = actions[rows]
        if mapping.time.resample_hz is not None:
            episode_times, episode_sensors, episode_actions = resample(
                episode_times, episode_sensors, episode_actions, mapping.time.resample_hz
            )
            logged.resampled_hz = mapping.time.resample_hz
        origin = episode_times[0] if mapping.time.start_at_zero else 0.0
        td = _episode(episode_sensors, episode_actions, episode_times - origin)
        validate_episode(
            td,
            sensor_order,
            action_dim=len(control_order),
            where=f"{path} episode {episode_label or 0}",
        )
        fill, success = float(fills[end - 1]), outcomes[end - 1]  # value at the last row
        meta = _meta(path, mapping, episode_label, rate, fill, success)
        episodes.append(
            ImportedEpisode(
                td,
                meta,
                path,
                episode_label,
                start + 1,
                logged,
                list(table.notes),
                dict(table.signal_gaps),
            )
        )
    return episodes


def read_episodes(
    path: str | Path,
    mapping: LogMapping,
    *,
    sensor_order: Sequence[str] | None = None,
    control_order: Sequence[str] | None = None,
) -> list[tuple[TensorDict, EpisodeMeta]]:
    """Read, check and convert one log file into (episode, metadata) pairs."""
    return [
        e.pair()
        for e in read_log_episodes(
            path, mapping, sensor_order=sensor_order, control_order=control_order
        )
    ]


def read_all(
    paths: str | Path | Iterable[str | Path],
    mapping: LogMapping | Mapping | str | Path,
    *,
    sensor_order: Sequence[str] | None = None,
    control_order: Sequence[str] | None = None,
) -> list[ImportedEpisode]:
    """``read_log_episodes`` over several files: every episode of every file, or the first
    error."""
    mapping = load_mapping(mapping)
    episodes: list[ImportedEpisode] = []
    for path in as_paths(paths):
        episodes += read_log_episodes(
            path, mapping, sensor_order=sensor_order, control_order=control_order
        )
    return episodes


def read_logs(
    paths: str | Path | Iterable[str | Path],
    mapping: LogMapping | Mapping | str | Path,
    *,
    sensor_order: Sequence[str] | None = None,
    control_order: Sequence[str] | None = None,
) -> list[tuple[TensorDict, EpisodeMeta]]:
    """``read_episodes`` over several files: every episode of every file, or the first error."""
    return [
        e.pair()
        for e in read_all(paths, mapping, sensor_order=sensor_order, control_order=control_order)
    ]


def as_paths(paths: str | Path | Iterable[str | Path]) -> list[Path]:
    if isinstance(paths, str | Path):
        return [Path(paths)]
    return [Path(p) for p in paths]
