"""The policy room's settings: the ``policy`` and ``sensors`` config groups.

``PolicyConfig`` (conf/policy/) names a registered controller and its options;
``SensorsConfig`` (conf/sensors/) names the controller inputs s and the attention inputs s'.
``check_controller`` checks the pair together (the controller can be built on those sensors
with those options and trained by the chosen trainer) before any work starts.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from omegaconf import MISSING

from pilerl import checks

from .config import ActorConfig
from .registry import CONTROLLERS, TRAINERS, build_policy, controller_inputs, get_spec


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
