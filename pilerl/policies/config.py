"""The policy room's settings.

``ActorConfig``: the small JSON-able description an actor is rebuilt from (saved beside its
weights). ``PolicyConfig`` and ``SensorsConfig``: the ``policy`` and ``sensors`` config
groups (conf/policy/, conf/sensors/); ``check_controller`` checks the pair together.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

from omegaconf import MISSING

from pilerl import checks

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


# Levenberg-Marquardt holds a [rows * controls, P] Jacobian and a [P, P] float64 system
# per step: 5,000 parameters need ~200 MB for the system; DANNet's ~48,000 would need
# ~18 GB (it grew to several GB and hung).
LM_MAX_PARAMETERS = 5_000
MAX_PARAMETERS = 10_000_000  # any controller: ~200x DANNet, 40 MB of float32 weights


def check_controller_choice(
    controller: str,
    sensors: Sequence[str],
    attention_sensors: Sequence[str] | None,
    options: dict,
    *,
    trainer: str | None = None,
) -> None:
    """Raise ``ValueError`` naming the field unless ``controller`` can be built on these
    sensors with ``options`` and trained by ``trainer`` (``None``: its default).

    Builds the controller once on unit statistics on torch's ``meta`` device (no memory,
    torch's RNG untouched), so options are checked by the controller itself and the
    parameters counted before anything is allocated; refuses Levenberg-Marquardt for a controller
    with more than ``LM_MAX_PARAMETERS`` parameters, and ``fit`` for anything but the
    random forest (which is always fit, whatever ``trainer`` says).
    """
    import torch

    from .registry import TRAINERS, build_policy, controller_inputs, get_spec

    try:
        spec = get_spec(controller)
    except KeyError as error:
        raise ValueError(f"policy.name: {error}") from None
    trainer = trainer or spec.trainer
    if trainer not in TRAINERS:
        raise ValueError(f"trainer: unknown {trainer!r}; known: {list(TRAINERS)}")
    if trainer == "fit" and spec.controller.differentiable:
        raise ValueError(
            f"trainer: 'fit' is for the random forest, not {controller!r} (the neural "
            "controllers use 'gradient' or 'levenberg_marquardt')"
        )
    s, s_prime = controller_inputs(controller, sensors, attention_sensors)
    unit = {"mean": 0.0, "std": 1.0, "min": -1.0, "max": 1.0}
    stats = {"sensors": {name: dict(unit) for name in [*s, *(s_prime or [])]}}
    # on the meta device: shapes only, no memory and no draw from torch's RNG
    with torch.device("meta"):
        try:
            policy = build_policy(
                ActorConfig(controller, s, stats, attention_sensors=s_prime, options=options)
            )
        except (TypeError, ValueError, RuntimeError) as error:
            raise ValueError(f"policy.options: {controller!r} refuses {options}: {error}") from None
    n_parameters = sum(p.numel() for p in policy.parameters())
    if n_parameters > MAX_PARAMETERS:
        raise ValueError(
            f"policy.options: {controller!r} with {options} has {n_parameters} parameters, "
            f"more than the {MAX_PARAMETERS} a controller here may have"
        )
    if trainer == "levenberg_marquardt" and n_parameters > LM_MAX_PARAMETERS:
        raise ValueError(
            f"trainer: Levenberg-Marquardt cannot train {controller!r}: it has {n_parameters} "
            f"parameters and LM solves a {n_parameters} x {n_parameters} system per step "
            f"(~{n_parameters**2 * 8 / 1e9:.1f} GB); the limit is {LM_MAX_PARAMETERS}. "
            "Use trainer=gradient"
        )


@dataclass
class PolicyConfig:
    """A controller (the ``policy`` config group): registry name and its options.

    Attributes:
        name: registered controller (``pilerl.policies.registry.CONTROLLERS``).
        options: keyword options of the controller class (empty: the paper's defaults).
    """

    name: str = MISSING
    options: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        from .registry import CONTROLLERS

        if self.name != MISSING:
            CONTROLLERS.check("policy.name", self.name)


@dataclass
class SensorsConfig:
    """Controller inputs s and attention inputs s' by sensor name (``sensors`` group)."""

    s: list[str] = MISSING
    s_prime: list[str] | None = None

    def __post_init__(self) -> None:
        if self.s != MISSING:
            checks.names("sensors.s", self.s)
        if self.s_prime is not None:
            checks.names("sensors.s_prime", self.s_prime)


def check_controller(policy: PolicyConfig, sensors: SensorsConfig, *, trainer: str | None) -> None:
    """The controller ``policy`` on ``sensors`` can be built with its options and trained
    by ``trainer`` (``None``: its default); see ``check_controller_choice``."""
    if MISSING in (policy.name, sensors.s):
        return
    check_controller_choice(
        policy.name, sensors.s, sensors.s_prime, policy.options, trainer=trainer
    )
