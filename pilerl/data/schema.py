"""The demonstration episode schema (version 1).

An episode is a TensorDict with batch size ``[T]`` (one row per recorded sample), laid
out like a TorchRL rollout so that TorchRL losses and replay buffers take it as is:

| key | shape | dtype | meaning |
|---|---|---|---|
| ``<sensor>`` for each sensor name | [T, 1] | float32 | reading, physical unit (index) |
| ``action`` | [T, A] | float32 | controls in [-1, 1] (boom, bucket, throttle) |
| ``time_s`` | [T] | float64 | time since the episode start [s] |
| ``step`` | [T] | int64 | sample index within the episode |
| ``episode`` | [T] | int64 | episode id within its dataset |
| ``("next", <sensor>)`` | [T, 1] | float32 | reading after the action |
| ``("next", "reward")`` | [T, 1] | float32 | reward (NaN where unknown, e.g. imported logs) |
| ``("next", "done" / "terminated" / "truncated")`` | [T, 1] | bool | episode end flags |

Per-episode metadata (``EpisodeMeta``) lives in the dataset index, not in the tensors.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import torch
from tensordict import TensorDict

SCHEMA_VERSION = 1
END_FLAGS = ("done", "terminated", "truncated")


class SchemaError(ValueError):
    """An episode or dataset does not follow the schema; the message says where."""


@dataclass
class EpisodeMeta:
    """What is known about one episode besides its samples.

    Attributes:
        rate_hz: sampling rate of the rows [Hz].
        source: ``sim``, ``teleop`` or ``import:<file>``.
        condition: condition name (``summer``...) or a free label for imported logs.
        condition_params: material / ground / hydraulics parameters, when known.
        soil: soil model name (simulated episodes).
        operator: operator description: ``{"id": ..., "kind": ..., "style": {...}}``.
        fill_fraction: final bucket fill (fraction of rated capacity), NaN if unknown.
        success: the paper's half-full rule at the end of the scoop, if known.
        seed: episode seed (simulated episodes).
        start: start pose, e.g. ``{"distance_m": 3.2, "approach_angle_rad": 0.05}``.
        id: episode id in its dataset (set by the store).
        n_samples: number of rows (set by the store).
    """

    rate_hz: float
    source: str = "sim"
    condition: str = "unknown"
    condition_params: dict = field(default_factory=dict)
    soil: str = ""
    operator: dict = field(default_factory=dict)
    fill_fraction: float = math.nan
    success: bool | None = None
    seed: int | None = None
    start: dict = field(default_factory=dict)
    id: int = -1
    n_samples: int = 0

    def to_json(self) -> dict:
        data = asdict(self)
        data["fill_fraction"] = None if math.isnan(self.fill_fraction) else self.fill_fraction
        return data

    @classmethod
    def from_json(cls, data: dict) -> EpisodeMeta:
        data = dict(data)
        if data.get("fill_fraction") is None:
            data["fill_fraction"] = math.nan
        return cls(**data)


def make_episode(
    *,
    sensors: dict[str, torch.Tensor],
    next_sensors: dict[str, torch.Tensor],
    actions: torch.Tensor,
    time_s: torch.Tensor,
    rewards: torch.Tensor | None = None,
    terminated: bool = False,
    truncated: bool = False,
) -> TensorDict:
    """Build a schema-conforming episode from per-sample arrays (length T each).

    ``sensors[name]`` is the reading before the action at each row, ``next_sensors``
    after it. The end flags are set on the last row only.
    """
    n = int(actions.shape[0])
    flags = torch.zeros(n, 1, dtype=torch.bool)
    done, term, trunc = flags.clone(), flags.clone(), flags.clone()
    if n:
        term[-1] = terminated
        trunc[-1] = truncated
        done[-1] = terminated or truncated
    reward = (
        torch.full((n, 1), math.nan, dtype=torch.float32)
        if rewards is None
        else torch.as_tensor(rewards, dtype=torch.float32).reshape(n, 1)
    )
    td = TensorDict(
        {
            **{
                k: torch.as_tensor(v, dtype=torch.float32).reshape(n, 1) for k, v in sensors.items()
            },
            "action": torch.as_tensor(actions, dtype=torch.float32).reshape(n, -1),
            "time_s": torch.as_tensor(time_s, dtype=torch.float64).reshape(n),
            "step": torch.arange(n, dtype=torch.int64),
            "episode": torch.full((n,), -1, dtype=torch.int64),
            "next": TensorDict(
                {
                    **{
                        k: torch.as_tensor(v, dtype=torch.float32).reshape(n, 1)
                        for k, v in next_sensors.items()
                    },
                    "reward": reward,
                    "done": done,
                    "terminated": term,
                    "truncated": trunc,
                },
                batch_size=[n],
            ),
        },
        batch_size=[n],
    )
    return td


def required_keys(sensor_names: Sequence[str]) -> list:
    """Every key an episode must have, nested keys as tuples."""
    return [
        *sensor_names,
        "action",
        "time_s",
        "step",
        "episode",
        *[("next", k) for k in (*sensor_names, "reward", *END_FLAGS)],
    ]


def validate_episode(
    td: TensorDict, sensor_names: Sequence[str], *, action_dim: int, where: str = "episode"
) -> None:
    """Raise ``SchemaError`` naming the key and row (0-based) if ``td`` breaks the schema."""
    if td.batch_dims != 1 or td.batch_size[0] == 0:
        raise SchemaError(f"{where}: expected a non-empty 1-D batch, got {tuple(td.batch_size)}")
    required = required_keys(sensor_names)
    keys = set(td.keys(include_nested=True, leaves_only=True))
    missing = [k for k in required if k not in keys]
    if missing:
        raise SchemaError(f"{where}: missing keys {missing}")
    for name in sensor_names:
        if tuple(td[name].shape) != (td.batch_size[0], 1):
            raise SchemaError(
                f"{where}: sensor {name!r} has shape {tuple(td[name].shape)}, "
                f"expected ({td.batch_size[0]}, 1)"
            )
    if td["action"].shape[-1] != action_dim:
        raise SchemaError(
            f"{where}: action has {td['action'].shape[-1]} controls, expected {action_dim}"
        )
    for key in [*sensor_names, "action", *[("next", k) for k in sensor_names]]:
        value = td[key]
        bad = ~torch.isfinite(value)
        if bad.any():
            row = int(bad.reshape(value.shape[0], -1).any(-1).nonzero()[0])
            raise SchemaError(f"{where}: non-finite value in {key!r} at row {row}")
    if (td["action"].abs() > 1.0 + 1e-6).any():
        row = int((td["action"].abs() > 1.0 + 1e-6).any(-1).nonzero()[0])
        raise SchemaError(f"{where}: action outside [-1, 1] at row {row}")
    time_s = td["time_s"]
    if not torch.isfinite(time_s).all():
        row = int((~torch.isfinite(time_s)).nonzero()[0])
        raise SchemaError(f"{where}: non-finite time_s at row {row}")
    if td.batch_size[0] > 1 and not (time_s[1:] > time_s[:-1]).all():
        row = int((time_s[1:] <= time_s[:-1]).nonzero()[0]) + 1
        raise SchemaError(f"{where}: time_s not strictly increasing at row {row}")
