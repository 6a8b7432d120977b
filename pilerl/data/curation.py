"""Dataset curation as in the paper: D_I (everything, full rate) and D_II (successful
episodes only, down-sampled), plus the normalisation statistics stored with a dataset."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import torch
from tensordict import TensorDict
from tqdm import tqdm

from .schema import END_FLAGS, EpisodeMeta
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

    Args:
        successful_only: keep only episodes whose ``success`` is True (the paper's D_II).
        rate_hz: down-sample to this rate; it must divide the source rate exactly.
            ``None`` keeps the recorded rate (the paper's D_I).
        keep: an extra episode filter (e.g. on condition).
    """
    chosen = [
        m
        for m in source.episodes
        if (not successful_only or m.success) and (keep is None or keep(m))
    ]
    if not chosen:
        raise ValueError(
            f"{source.root}: no episodes left after curation (successful_only={successful_only})"
        )
    target = EpisodeStore.create(
        out_root, sensors=source.sensors, controls=source.controls, description=description
    )
    for meta in tqdm(
        chosen, desc=f"building {Path(out_root).name}", unit="episode", disable=not progress
    ):
        episode = source.load(meta.id).to_tensordict()
        factor = 1
        if rate_hz is not None:
            ratio = meta.rate_hz / rate_hz
            factor = round(ratio)
            if factor < 1 or not math.isclose(ratio, factor, rel_tol=1e-6):
                raise ValueError(
                    f"{source.root} episode {meta.id}: rate {meta.rate_hz} Hz is "
                    f"not a whole multiple of {rate_hz} Hz"
                )
        new_meta = EpisodeMeta.from_json({**meta.to_json(), "rate_hz": meta.rate_hz / factor})
        new_meta.operator = {**new_meta.operator, "source_episode": meta.id}
        target.append(downsample_episode(episode, factor), new_meta)
    target.set_stats(compute_stats(target))
    return target


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
