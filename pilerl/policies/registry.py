"""The one registry of controllers: name -> how to build it and how it is trained.

``make_controller`` builds a ``SensorPolicy`` (normaliser + controller) for the given
sensors; ``pilerl.policies.actors.make_actor`` wraps it as a TorchRL actor. An unknown
name fails with the list of known ones.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from pilerl.registry import Registry, UnknownNameError

from .attention import ANNet, DANNet
from .config import ActorConfig
from .controllers import NNet, NNetV2
from .policy import SensorPolicy
from .random_forest import RandomForestController

TRAINERS = ("levenberg_marquardt", "gradient", "fit")


UnknownControllerError = UnknownNameError  # raised for a controller name not registered


@dataclass(frozen=True)
class ControllerSpec:
    """A registered controller.

    Attributes:
        name: registry name.
        controller: the class; called as ``controller(n_s, n_u, **options)``, with
            ``n_attention_inputs=n_s'`` added for attention controllers.
        reference: where it comes from.
        trainer: default training: ``levenberg_marquardt`` (``fit_lm``), ``gradient``
            (BC with a first-order optimiser; RAdam, batch 512, lr 1e-3 in the paper) or
            ``fit`` (``RandomForestActor.fit``).
        uses_attention: reads attention inputs s'.
    """

    name: str
    controller: Callable
    reference: str
    trainer: str
    uses_attention: bool = False


CONTROLLERS: Registry[ControllerSpec] = Registry(
    "controller",
    {
        spec.name: spec
        for spec in (
            ControllerSpec("nnet", NNet, "Halbach et al. 2019", "levenberg_marquardt"),
            ControllerSpec("nnetv2", NNetV2, "revised paper, NNetV2", "gradient"),
            ControllerSpec("annet", ANNet, "revised paper, ANNet", "gradient", uses_attention=True),
            ControllerSpec(
                "dannet", DANNet, "revised paper, DANNet", "gradient", uses_attention=True
            ),
            ControllerSpec("rf", RandomForestController, "Yang et al. 2020 (ICRA)", "fit"),
        )
    },
)
NEURAL_CONTROLLERS = tuple(n for n, s in CONTROLLERS.items() if s.controller.differentiable)


def available_controllers() -> list[str]:
    """Registered controller names, sorted."""
    return sorted(CONTROLLERS)


def get_spec(name: str) -> ControllerSpec:
    """The registered controller ``name``; unknown names fail with the list of known ones."""
    return CONTROLLERS[name]


def build_policy(config: ActorConfig) -> SensorPolicy:
    """A freshly initialised ``SensorPolicy`` for ``config`` (weights from torch's RNG)."""
    spec = get_spec(config.controller)
    if config.attention_sensors is not None and not spec.uses_attention:
        raise ValueError(
            f"controller {spec.name!r} has no attention network: attention_sensors "
            f"{config.attention_sensors} cannot be used"
        )
    kwargs = dict(config.options)
    if spec.uses_attention:
        kwargs["n_attention_inputs"] = len(config.attention_sensors or config.sensors)
    controller = spec.controller(len(config.sensors), config.n_controls, **kwargs)
    return SensorPolicy(config, controller)


def controller_inputs(
    name: str, sensors: Sequence[str], attention_sensors: Sequence[str] | None
) -> tuple[list[str], list[str] | None]:
    """The (s, s') a controller reads when a sensor set names s and s'.

    Attention controllers read s and s' as given. A controller without attention has no
    place for s': its sensors become plain inputs, s followed by those of s' not in s (the
    paper's "NNetV2 with p_t and s'" row; its Fig. 4 calls training with s' "fusion").
    """
    sensors = list(sensors)
    if attention_sensors is None or get_spec(name).uses_attention:
        return sensors, None if attention_sensors is None else list(attention_sensors)
    return sensors + [s for s in attention_sensors if s not in sensors], None


def make_controller(
    name: str,
    *,
    sensors: Sequence[str],
    stats: dict,
    attention_sensors: Sequence[str] | None = None,
    options: dict | None = None,
) -> SensorPolicy:
    """Build controller ``name`` reading ``sensors`` (s) and ``attention_sensors`` (s').

    Args:
        sensors: controller inputs s, e.g. ``["boom_angle", "bucket_angle",
            "drive_pressure", "telescope_pressure"]``.
        stats: ``compute_stats`` output of the training dataset (normalisation).
        attention_sensors: s' for ``annet`` / ``dannet``; ``None`` means s' = s.
        options: controller hyperparameters (see the controller classes).
    """
    get_spec(name)  # unknown names fail before the config is checked
    config = ActorConfig(
        controller=name,
        sensors=list(sensors),
        stats=stats,
        attention_sensors=None if attention_sensors is None else list(attention_sensors),
        options=dict(options or {}),
    )
    return build_policy(config)
