"""Dataset curation as in the paper: D_I (everything, full rate) and D_II (successful
episodes only, down-sampled), plus the normalisation statistics stored with a dataset.

``build_dataset`` is atomic and resumable (see its docstring): recipes call it directly."""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import math
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import torch
from tensordict import TensorDict
from tqdm import tqdm

from .schema import END_FLAGS, EpisodeMeta, SchemaError
from .store import EpisodeStore


def downsample_episode(episode: TensorDict, factor: int) -> TensorDict:
    """Keep rows 0, f, 2f, ... of an episode; ``next`` becomes the next kept row's reading.

    Row k of the result equals row ``k * factor`` of the input (sensors, action, time).
    Its ``next`` readings are those f rows later (the original ``next`` of the last row
    for the final kept row), and the end flags move to the final kept row.
    """
    if factor < 1:
        raise ValueError(f"downsample_episode: factor must be >= 1, got {factor}")
    n = episode.batch_size[0]
    kept = torch.arange(0, n, factor)
    out = episode[kept].clone()
    following = kept + factor
    has_next_row = following < n
    # .keys(): iterating a TensorDict walks its batch dimension, not its keys
    sensor_keys = [k for k in episode["next"].keys() if k not in ("reward", *END_FLAGS)]  # noqa: SIM118
    for key in sensor_keys:
        nxt = out["next", key].clone()
        nxt[has_next_row] = episode[key][following[has_next_row]]
        nxt[~has_next_row] = episode["next", key][-1]
        out["next", key] = nxt
    reward = episode["next", "reward"]
    out["next", "reward"] = torch.stack([reward[i : i + factor].sum(0) for i in kept.tolist()])
    for flag in END_FLAGS:
        values = torch.zeros_like(out["next", flag])
        values[-1] = episode["next", flag][-1]
        out["next", flag] = values
    out["step"] = torch.arange(len(kept), dtype=torch.int64)
    return out


def build_dataset(
    source: EpisodeStore,
    out_root: str | Path,
    *,
    successful_only: bool,
    rate_hz: float | None,
    description: str = "",
    keep: Callable[[EpisodeMeta], bool] | None = None,
    progress: bool = True,
) -> EpisodeStore:
    """Curate ``source`` into a new dataset at ``out_root`` and store its statistics.

    The build is atomic: the dataset is written into a hidden directory beside
    ``out_root`` and renamed to ``out_root`` once complete (statistics included), so a
    killed build leaves no dataset at ``out_root`` and the same call simply runs again
    (clearing the killed build's leftovers). A complete dataset already at ``out_root``
    that was built by the same rule from the same source is returned as it is (a resumed
    pipeline or sweep skips the step); any other existing directory is refused.
    Every argument and every chosen episode's rate is checked before anything is written.

    Args:
        successful_only: keep only episodes whose ``success`` is True (the paper's D_II).
        rate_hz: down-sample to this rate; it must divide the source rate exactly.
            ``None`` keeps the recorded rate (the paper's D_I).
        keep: an extra episode filter (e.g. on condition); a dataset built with one is
            never reused.
    """
    out_root = Path(out_root)
    if rate_hz is not None and not (
        isinstance(rate_hz, int | float) and math.isfinite(rate_hz) and rate_hz > 0
    ):
        raise ValueError(f"build_dataset: rate_hz must be a finite number > 0, got {rate_hz!r}")
    rule = {
        "source": str(Path(source.root).resolve()),
        "source_episodes": len(source),
        # what the episodes are (operator styles, seeds, fills...): a dataset built from
        # an earlier recording at the same path is not taken for this one's
        "source_sha256": episodes_digest(source),
        "successful_only": bool(successful_only),
        "rate_hz": rate_hz,
        "filtered": keep is not None,
    }
    chosen = [
        m
        for m in source.episodes
        if (not successful_only or m.success) and (keep is None or keep(m))
    ]
    if not chosen:
        raise ValueError(
            f"{source.root}: no episodes left after curation (successful_only={successful_only})"
        )
    factors = [_downsampling_factor(source, meta, rate_hz) for meta in chosen]
    with _dataset_build(out_root) as scratch:
        if out_root.exists() and not (out_root.is_dir() and not any(out_root.iterdir())):
            return _finished_build(out_root, rule)
        target = EpisodeStore.create(
            scratch, sensors=source.sensors, controls=source.controls, description=description
        )
        for meta, factor in tqdm(
            list(zip(chosen, factors, strict=True)),
            desc=f"building {out_root.name}",
            unit="episode",
            disable=not progress,
        ):
            episode = source.load(meta.id).to_tensordict()
            new_meta = EpisodeMeta.from_json({**meta.to_json(), "rate_hz": meta.rate_hz / factor})
            new_meta.operator = {**new_meta.operator, "source_episode": meta.id}
            target.append(downsample_episode(episode, factor), new_meta)
        target.set_index_entry("curation", rule)
        target.set_stats(compute_stats(target))
        scratch.rename(out_root)  # atomic; replaces an empty directory
    return EpisodeStore.open(out_root)


BUILD_PREFIX = ".building-"


def episodes_digest(store: EpisodeStore) -> str:
    """SHA-256 of ``store``'s episode list (every episode's metadata: source, condition,
    operator and its style, seed, start, fill, success, rate, length), in id order."""
    episodes = [meta.to_json() for meta in sorted(store.episodes, key=lambda m: m.id)]
    text = json.dumps(episodes, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def _downsampling_factor(source: EpisodeStore, meta: EpisodeMeta, rate_hz: float | None) -> int:
    if rate_hz is None:
        return 1
    ratio = meta.rate_hz / rate_hz
    factor = round(ratio)
    if factor < 1 or not math.isclose(ratio, factor, rel_tol=1e-6):
        raise ValueError(
            f"{source.root} episode {meta.id}: rate {meta.rate_hz} Hz is "
            f"not a whole multiple of {rate_hz} Hz"
        )
    return factor


@contextlib.contextmanager
def _dataset_build(out_root: Path) -> Iterator[Path]:
    """A fresh hidden directory beside ``out_root`` to build into, under a lock on the
    parent directory (``flock``; no lock file is left behind, and builds into one parent
    directory take turns); leftovers of killed builds of the same name are removed
    first, and the scratch directory is removed on any failure."""
    parent = out_root.parent
    parent.mkdir(parents=True, exist_ok=True)
    prefix = f".{out_root.name}{BUILD_PREFIX}"
    descriptor = os.open(parent, os.O_RDONLY)
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX)
        for leftover in parent.glob(f"{prefix}*"):
            shutil.rmtree(leftover, ignore_errors=True)
        scratch = Path(tempfile.mkdtemp(prefix=prefix, dir=parent))
        try:
            yield scratch
        finally:
            shutil.rmtree(scratch, ignore_errors=True)
    finally:
        os.close(descriptor)  # releases the lock


def _finished_build(out_root: Path, rule: dict) -> EpisodeStore:
    """The dataset already at ``out_root`` if the same rule built it, else a clear error."""
    try:
        existing = EpisodeStore.open(out_root)
    except (FileNotFoundError, SchemaError) as error:
        raise FileExistsError(
            f"{out_root}: exists and is not a dataset ({error}); choose another out_dir"
        ) from None
    built_by = existing.index_entry("curation")
    if rule["filtered"] or built_by != rule or existing.stats is None:
        raise FileExistsError(
            f"{out_root}: a dataset already exists here, built by {built_by}, not by {rule}; "
            "choose another out_dir"
        )
    return existing


def compute_stats(store: EpisodeStore) -> dict:
    """Per-sensor and per-control mean, std, min and max over every sample of ``store``."""
    data = store.to_tensordict()

    def summary(values: torch.Tensor) -> dict:
        values = values.double()
        return {
            "mean": values.mean(0).tolist(),
            "std": values.std(0).clamp_min(1e-8).tolist(),
            "min": values.min(0).values.tolist(),
            "max": values.max(0).values.tolist(),
        }

    return {
        "n_samples": int(data.batch_size[0]),
        "sensors": {
            name: {k: v[0] for k, v in summary(data[name]).items()} for name in store.sensors
        },
        "action": summary(data["action"]),
    }
