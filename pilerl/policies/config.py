"""The small JSON-able description an actor is rebuilt from (saved beside its weights)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

DEFAULT_N_CONTROLS = 3  # boom, bucket, throttle


@dataclass
class ActorConfig:
    """Everything needed to rebuild an actor's modules before loading its weights.

    Attributes:
        controller: registered controller name (``nnet``, ``nnetv2``, ``annet``, ``dannet``,
            ``rf``; see ``pilerl.policies.registry``).
        sensors: controller inputs s, in order (e.g. ``["boom_angle", "bucket_angle",
            "drive_pressure", "telescope_pressure"]``).
        attention_sensors: attention inputs s' for ANNet / DANNet; ``None`` means s' = s.
            Ignored (must be ``None``) for controllers without attention.
        stats: dataset statistics as written by ``pilerl.data.curation.compute_stats``;
            only the entries of the sensors used (and ``action``) are kept.
        n_controls: size of ``action`` (3 on the pile loader); by default read from
            ``stats["action"]["mean"]`` when present.
        options: controller hyperparameters passed to its builder (e.g. ``{"seed": 1}``
            for ``rf``); empty means the paper's defaults.
    """

    controller: str
    sensors: list[str]
    stats: dict
    attention_sensors: list[str] | None = None
    n_controls: int | None = None
    options: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.sensors = _checked_names(self.sensors, "sensors")
        if self.attention_sensors is not None:
            self.attention_sensors = _checked_names(self.attention_sensors, "attention_sensors")
        stats_sensors = (self.stats or {}).get("sensors", {})
        missing = [name for name in self.input_keys if name not in stats_sensors]
        if missing:
            raise ValueError(
                f"ActorConfig: no statistics for sensors {missing}; the stats know "
                f"{sorted(stats_sensors)}"
            )
        for name in self.input_keys:
            entry = stats_sensors[name]
            for key in ("mean", "std"):
                value = entry.get(key)
                if not isinstance(value, int | float) or not math.isfinite(value):
                    raise ValueError(f"ActorConfig: stats for {name!r} have {key}={value!r}")
        action_stats = self.stats.get("action")
        if self.n_controls is None:
            self.n_controls = (
                len(action_stats["mean"])
                if action_stats and "mean" in action_stats
                else DEFAULT_N_CONTROLS
            )
        if self.n_controls < 1:
            raise ValueError(f"ActorConfig: n_controls must be >= 1, got {self.n_controls}")
        # keep only what this actor uses: the saved config stays small
        kept = {"sensors": {name: dict(stats_sensors[name]) for name in self.input_keys}}
        if action_stats is not None:
            kept["action"] = dict(action_stats)
        self.stats = kept
        self.options = dict(self.options)

    @property
    def input_keys(self) -> list[str]:
        """Every sensor key the actor reads: s first, then the extra s' sensors."""
        extra = [k for k in (self.attention_sensors or []) if k not in self.sensors]
        return [*self.sensors, *extra]

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, data: dict) -> ActorConfig:
        return cls(**data)


def _checked_names(names: Sequence[str], what: str) -> list[str]:
    if isinstance(names, str):
        raise TypeError(f"ActorConfig: {what} must be a list of sensor names, not {names!r}")
    names = list(names)
    if not names:
        raise ValueError(f"ActorConfig: {what} is empty")
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise ValueError(f"ActorConfig: {what} lists {duplicates} more than once")
    return names
