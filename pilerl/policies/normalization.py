"""Z-score normalisation of named sensor readings, with the statistics kept as buffers.

The buffers travel with the actor's ``state_dict``, so a saved actor normalises exactly as
it did in training, whatever dataset is at hand when it is loaded.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

MIN_STD = 1e-6  # a constant sensor would otherwise divide by zero


class InputNormalizer(nn.Module):
    """``(x - mean) / std`` over the last dimension, one entry per named sensor.

    Attributes:
        names: sensor names, in the order of the last dimension of the input.
        mean, std: buffers of shape ``[len(names)]`` in the sensors' physical units.
    """

    mean: torch.Tensor
    std: torch.Tensor

    def __init__(
        self, names: Sequence[str], *, mean: Sequence[float], std: Sequence[float]
    ) -> None:
        super().__init__()
        self.names = list(names)
        mean_t = torch.as_tensor(list(mean), dtype=torch.float32)
        std_t = torch.as_tensor(list(std), dtype=torch.float32)
        if mean_t.shape != (len(self.names),) or std_t.shape != (len(self.names),):
            raise ValueError(
                f"InputNormalizer: {len(self.names)} names but mean {tuple(mean_t.shape)} "
                f"and std {tuple(std_t.shape)}"
            )
        self.register_buffer("mean", mean_t)
        self.register_buffer("std", std_t.clamp_min(MIN_STD))

    @classmethod
    def from_stats(cls, names: Sequence[str], stats: dict) -> InputNormalizer:
        """Build from ``pilerl.data.curation.compute_stats`` output (``stats["sensors"]``)."""
        sensors = stats.get("sensors", {})
        missing = [name for name in names if name not in sensors]
        if missing:
            raise KeyError(f"InputNormalizer: no stats for {missing}; known: {sorted(sensors)}")
        return cls(
            names,
            mean=[float(sensors[n]["mean"]) for n in names],
            std=[float(sensors[n]["std"]) for n in names],
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return (x - self.mean) / self.std

    def inverse(self, z: torch.Tensor) -> torch.Tensor:
        """Back to physical units."""
        return z * self.std + self.mean

    def extra_repr(self) -> str:
        return f"names={self.names}"
