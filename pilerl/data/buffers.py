"""Demonstrations in TorchRL replay buffers, with the usual samplers."""

from __future__ import annotations

from pathlib import Path

from tensordict import TensorDict
from torchrl.data import LazyMemmapStorage, LazyTensorStorage, TensorDictReplayBuffer
from torchrl.data.replay_buffers import (
    RandomSampler,
    SamplerWithoutReplacement,
    SliceSampler,
)

SAMPLERS = ("uniform", "without_replacement", "slices")


def make_replay_buffer(
    data: TensorDict,
    *,
    batch_size: int,
    sampler: str = "uniform",
    slice_len: int | None = None,
    storage: str = "memory",
    scratch_dir: str | Path | None = None,
) -> TensorDictReplayBuffer:
    """A ``TensorDictReplayBuffer`` filled with ``data`` (batch ``[N]``).

    Args:
        sampler: ``uniform`` (with replacement), ``without_replacement`` (epochs), or
            ``slices`` (contiguous pieces of ``slice_len`` rows within one episode, split
            by the ``episode`` key; ``batch_size`` must be a multiple of ``slice_len``).
        storage: ``memory`` (LazyTensorStorage) or ``memmap`` (LazyMemmapStorage under
            ``scratch_dir``).
    """
    n = int(data.batch_size[0])
    if storage == "memory":
        store = LazyTensorStorage(n)
    elif storage == "memmap":
        store = LazyMemmapStorage(n, scratch_dir=scratch_dir)
    else:
        raise ValueError(f"unknown storage {storage!r}; known: ['memory', 'memmap']")
    if sampler == "uniform":
        chosen = RandomSampler()
    elif sampler == "without_replacement":
        chosen = SamplerWithoutReplacement()
    elif sampler == "slices":
        if not slice_len or batch_size % slice_len:
            raise ValueError(
                f"sampler 'slices': batch_size {batch_size} must be a multiple of "
                f"slice_len {slice_len}"
            )
        # the demonstrations do not change after extend: cache the episode boundaries
        chosen = SliceSampler(
            slice_len=slice_len, traj_key="episode", strict_length=False, cache_values=True
        )
    else:
        raise ValueError(f"unknown sampler {sampler!r}; known: {list(SAMPLERS)}")
    buffer = TensorDictReplayBuffer(storage=store, sampler=chosen, batch_size=batch_size)
    buffer.extend(data)
    return buffer
