"""Typed config schemas registered in Hydra's ConfigStore.

The YAML files under conf/ extend these schemas, so a wrong type or an unknown key fails
when Hydra composes the config, before any work starts. Recipes turn a config into plain
library arguments once, at their boundary (``EnvConfig.make_kwargs``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING

from pilerl.operators import OperatorStyle

from . import checks

MAX_ANGLE_DEG = 90.0  # approach angles beyond this face away from the pile


@dataclass
class EnvConfig:
    """Which simulator to build and with what arguments.

    Attributes:
        simulator: plugin name (``pile_loader``, ``toy_cart``...).
        condition: condition preset (``summer``, ``winter_a`` .. ``winter_d``).
        soil: soil model (``heightfield`` or ``particles``).
        soil_options: keyword options of the soil model (e.g. ``{max_particles: 350}``).
        condition_overrides: changes to the condition's physical values, by part and field
            (e.g. ``{ground: {tyre_friction: 0.08}}``); checked by the simulator.
        control_hz: control rate [Hz].
        physics_hz: physics rate [Hz] (>= 500).
        sensor_noise: multiplier of the sensors' default noise (0 = noiseless).
        start_distance_range_m: cutting edge to pile toe at reset [m], (low, high).
        approach_angle_range_deg: heading relative to the pile normal [deg], (low, high).
    """

    simulator: str = "pile_loader"
    condition: str = "summer"
    soil: str = "heightfield"
    soil_options: dict[str, Any] = field(default_factory=dict)
    condition_overrides: dict[str, dict[str, float]] = field(default_factory=dict)
    control_hz: float = 20.0
    physics_hz: float = 500.0
    sensor_noise: float = 1.0
    start_distance_range_m: list[float] = field(default_factory=lambda: [1.0, 5.0])
    approach_angle_range_deg: list[float] = field(default_factory=lambda: [-10.0, 10.0])

    def __post_init__(self) -> None:
        from pilerl.sim import available_simulators

        checks.one_of("env.simulator", self.simulator, available_simulators())
        checks.name("env.condition", self.condition)
        checks.name("env.soil", self.soil)
        checks.positive("env.control_hz", self.control_hz)
        checks.positive("env.physics_hz", self.physics_hz)
        if self.physics_hz < self.control_hz:
            raise ValueError(
                f"env.physics_hz ({self.physics_hz}) must be >= env.control_hz "
                f"({self.control_hz}): each control step runs at least one physics step"
            )
        checks.non_negative("env.sensor_noise", self.sensor_noise)
        checks.interval("env.start_distance_range_m", self.start_distance_range_m, low=0.0)
        checks.interval(
            "env.approach_angle_range_deg",
            self.approach_angle_range_deg,
            low=-MAX_ANGLE_DEG,
            high=MAX_ANGLE_DEG,
        )
        for part, values in self.condition_overrides.items():
            if not isinstance(values, dict):
                raise ValueError(f"env.condition_overrides.{part}: must map fields to numbers")
            for key, value in values.items():
                checks.finite(f"env.condition_overrides.{part}.{key}", value)

    def make_kwargs(self, **overrides) -> dict:
        """Keyword arguments for ``pilerl.sim.make_gym_env`` (simulator name excluded)."""
        kwargs = {k: v for k, v in asdict(self).items() if k != "simulator"}
        if not kwargs["condition_overrides"]:  # simulators without conditions need not know it
            del kwargs["condition_overrides"]
        kwargs["start_distance_range_m"] = tuple(kwargs["start_distance_range_m"])
        kwargs["approach_angle_range_deg"] = tuple(kwargs["approach_angle_range_deg"])
        kwargs.update(overrides)
        return kwargs


@dataclass
class ScoopConfig:
    """The scoop recipe: scripted scoops recorded, rendered and reported per condition.

    Attributes:
        env: simulator arguments; ``env.condition`` is replaced by each of ``conditions``.
        operator: scripted operator style (``pilerl.operators.OperatorStyle``).
        conditions: conditions to scoop in, one episode each.
        seed: episode seed (start distance and approach angle follow from it).
        video: write an mp4 per condition: ``auto`` (when this machine can render, else
            one warning), ``true`` (refuse before any work if it cannot) or ``false``.
        render_width, render_height: video frame size [px].
        camera: MJCF camera for the video.
    """

    env: EnvConfig = field(default_factory=EnvConfig)
    operator: OperatorStyle = field(default_factory=OperatorStyle)
    conditions: list[str] = field(default_factory=lambda: ["summer", "winter_c"])
    seed: int = 0
    video: str = "auto"
    render_width: int = 640
    render_height: int = 360
    camera: str = "side"
    output_dir: str = MISSING  # set by the primary YAML to Hydra's run directory

    def __post_init__(self) -> None:
        checks.names("conditions", self.conditions)
        checks.non_negative_int("seed", self.seed)
        checks.render_size("", self.render_width, self.render_height)
        checks.name("camera", self.camera)
        checks.video_choice("video", self.video)


@dataclass
class RecordConfig:
    """The record recipe: scripted demonstrations into a dataset directory.

    Attributes:
        env: simulator arguments; ``env.control_hz`` is replaced by ``record_hz``.
        n_episodes: episodes to record (the paper: 72 summer demonstrations).
        seed: base seed (episode i: env seed ``seed * 100000 + i``, its own style).
        record_hz: sampling (= control) rate of the recording [Hz] (the paper: 500).
        trigger_sensor: the operators' impact cue (``drive_pressure`` or
            ``telescope_pressure``; see ``pilerl.operators.sample_style``).
        mistake_rate: share of operators who raise the boom too early.
        workers: recording processes.
        out_dir: dataset directory; an existing one is resumed.
    """

    env: EnvConfig = field(default_factory=EnvConfig)
    n_episodes: int = 72
    seed: int = 0
    record_hz: float = 500.0
    trigger_sensor: str = "drive_pressure"
    mistake_rate: float = 0.28
    workers: int = 2
    out_dir: str = MISSING

    def __post_init__(self) -> None:
        from pilerl.operators.scripted import TRIGGER_RANGES_MPA

        checks.positive_int("n_episodes", self.n_episodes)
        checks.non_negative_int("seed", self.seed)
        checks.positive("record_hz", self.record_hz)
        if self.env.physics_hz < self.record_hz:
            raise ValueError(
                f"record_hz ({self.record_hz}) must be <= env.physics_hz ({self.env.physics_hz})"
            )
        checks.one_of("trigger_sensor", self.trigger_sensor, sorted(TRIGGER_RANGES_MPA))
        checks.fraction("mistake_rate", self.mistake_rate)
        checks.positive_int("workers", self.workers)
        if self.out_dir != MISSING:
            checks.path("out_dir", self.out_dir)


@dataclass
class DatasetConfig:
    """A curation rule (the ``dataset`` config group).

    Attributes:
        name: ``d_i`` or ``d_ii`` (or your own).
        successful_only: keep only episodes that ended at least half full.
        rate_hz: down-sample to this rate [Hz]; ``None`` keeps the recorded rate.
    """

    name: str = MISSING
    successful_only: bool = False
    rate_hz: float | None = None

    def __post_init__(self) -> None:
        if self.name != MISSING:
            checks.name("dataset.name", self.name)
        if self.rate_hz is not None:
            checks.positive("dataset.rate_hz", self.rate_hz)


@dataclass
class BuildDatasetConfig:
    """The build_dataset recipe: a curated dataset from recorded demonstrations."""

    dataset: DatasetConfig = field(default_factory=DatasetConfig)
    source: str = MISSING
    out_dir: str = MISSING

    def __post_init__(self) -> None:
        if MISSING in (self.source, self.out_dir):
            return
        checks.path("source", self.source)
        checks.path("out_dir", self.out_dir)
        if Path(self.source).resolve() == Path(self.out_dir).resolve():
            raise ValueError(f"out_dir: must differ from source ({self.source!r})")


@dataclass
class TeleopConfig:
    """The teleop recipe: keyboard-driven episodes recorded like scripted ones."""

    env: EnvConfig = field(default_factory=EnvConfig)
    episodes: int = 1
    seed: int = 0
    operator_id: str = "person-1"
    out_dir: str = MISSING

    def __post_init__(self) -> None:
        checks.positive_int("episodes", self.episodes)
        checks.non_negative_int("seed", self.seed)
        checks.name("operator_id", self.operator_id)


LOGGER_BACKENDS = ("csv", "tensorboard", "wandb", "none")


@dataclass
class LoggerConfig:
    """A TorchRL metric logger (the ``logger`` config group).

    Attributes:
        backend: ``csv`` (default; files under the run directory), ``tensorboard`` (needs the
            ``tensorboard`` package) or ``none``.
    """

    backend: str = "csv"

    def __post_init__(self) -> None:
        if self.backend not in LOGGER_BACKENDS:
            raise ValueError(
                f"logger.backend: unknown {self.backend!r}; known: {list(LOGGER_BACKENDS)}"
            )


@dataclass
class PolicyConfig:
    """A controller (the ``policy`` config group): registry name and its options."""

    name: str = MISSING
    options: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        from pilerl.policies import available_controllers

        if self.name != MISSING:
            checks.one_of("policy.name", self.name, available_controllers())


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


@dataclass
class ClosedLoopConfig:
    """Closed-loop evaluation: N seeded episodes per condition (``pilerl.evaluation``).

    Attributes:
        conditions: conditions to test in; two or more ``winter_*`` are also pooled.
        episodes: episodes per condition (0 = no closed-loop evaluation).
        seed: base seed; episode i starts from the same pose in every condition.
        workers: episode processes (``None`` = one per core).
        videos: render the median-fill episode and the first failure of each condition:
            ``auto`` (when this machine can render, else one warning), ``true`` (refuse
            before any work if it cannot) or ``false``.
        video_conditions: only these conditions' (``None``: every condition's); offscreen
            rendering runs in software here (~0.05-0.2 s a frame).
        render_width, render_height: video frame size [px].
    """

    conditions: list[str] = field(
        default_factory=lambda: ["summer", "winter_a", "winter_b", "winter_c", "winter_d"]
    )
    episodes: int = 10
    seed: int = 1
    workers: int | None = None
    videos: str = "false"
    video_conditions: list[str] | None = None
    render_width: int = 640
    render_height: int = 360

    def __post_init__(self) -> None:
        checks.names("evaluation.conditions", self.conditions)
        checks.non_negative_int("evaluation.episodes", self.episodes)
        checks.non_negative_int("evaluation.seed", self.seed)
        if self.workers is not None:
            checks.positive_int("evaluation.workers", self.workers)
        if self.video_conditions is not None:
            checks.names("evaluation.video_conditions", self.video_conditions)
            unknown = [c for c in self.video_conditions if c not in self.conditions]
            if unknown:
                raise ValueError(
                    f"evaluation.video_conditions: {unknown} are not evaluated; "
                    f"evaluation.conditions are {list(self.conditions)}"
                )
        checks.render_size("evaluation.", self.render_width, self.render_height)
        checks.video_choice("evaluation.videos", self.videos)

    def plan(self, env: EnvConfig):
        """The ``EvaluationPlan`` of this config in ``env`` (its condition is replaced)."""
        from pilerl.evaluation.evaluator import EvaluationPlan

        kwargs = env.make_kwargs()
        kwargs.pop("condition")
        return EvaluationPlan(
            env.simulator, kwargs, tuple(self.conditions), self.episodes, seed=self.seed
        )


@dataclass
class EvaluateConfig:
    """The evaluate recipe: a controller tested in closed loop.

    Attributes:
        env: simulator arguments (``env.condition`` is replaced by each evaluated one).
        checkpoint: a saved actor (``best.pt`` of train_bc or finetune); ``None`` evaluates
            the scripted operator with the ``operator`` style.
        name: the controller's name in plots and tables (default: from the checkpoint).
        operator: scripted operator style (used when ``checkpoint`` is ``None``).
        evaluation: conditions, episodes, seed, workers, videos.
    """

    env: EnvConfig = field(default_factory=EnvConfig)
    checkpoint: str | None = None
    name: str | None = None
    operator: OperatorStyle = field(default_factory=OperatorStyle)
    evaluation: ClosedLoopConfig = field(default_factory=ClosedLoopConfig)
    output_dir: str = MISSING

    def __post_init__(self) -> None:
        if self.checkpoint is not None:
            checks.path("checkpoint", self.checkpoint)
        if self.name is not None:
            checks.name("name", self.name)


@dataclass
class TrainBCConfig:
    """The train_bc recipe: behaviour cloning of one controller on one dataset.

    Attributes:
        train_data: training dataset directory (``recipes/build_dataset.py``).
        validation_data: held-out demonstrations for the validation loss, or ``None``.
        epochs, batch_size, learning_rate, seed: ``pilerl.training.BCSettings``.
        gradient_steps: if set, replaces ``epochs`` for gradient training by as many epochs
            as give about this many steps (at least one), so datasets of different sizes
            get the same training budget (D_I has 27x the rows of D_II). Levenberg-Marquardt
            rounds and the forest's fit do not depend on the dataset size; they keep
            ``epochs``.
        logger: the TorchRL metric logger (``logger`` group: csv, tensorboard, none).
        trainer: ``gradient``, ``levenberg_marquardt`` or ``fit``; ``None`` = the
            controller's default (NNet: Levenberg-Marquardt).
        ensemble_seeds: > 1 trains that many seeds at once (``torch.func``) and plots
            mean +- std curves (the paper's Fig. 4) instead of one model.
        env, evaluation: the closed-loop test of the trained controller (the last step;
            ``evaluation.episodes: 0`` skips it), written to ``<run dir>/evaluation``.
    """

    policy: PolicyConfig = field(default_factory=PolicyConfig)
    sensors: SensorsConfig = field(default_factory=SensorsConfig)
    train_data: str = MISSING
    validation_data: str | None = None
    epochs: int = 150
    gradient_steps: int | None = None
    batch_size: int = 512
    learning_rate: float = 1e-3
    seed: int = 0
    logger: LoggerConfig = field(default_factory=LoggerConfig)
    trainer: str | None = None
    ensemble_seeds: int = 1
    env: EnvConfig = field(default_factory=EnvConfig)
    evaluation: ClosedLoopConfig = field(default_factory=lambda: ClosedLoopConfig(episodes=0))
    output_dir: str = MISSING

    def __post_init__(self) -> None:
        from pilerl.policies.registry import TRAINERS

        if self.train_data != MISSING:
            checks.path("train_data", self.train_data)
        if self.validation_data is not None:
            checks.path("validation_data", self.validation_data)
        checks.positive_int("epochs", self.epochs)
        if self.gradient_steps is not None:
            checks.positive_int("gradient_steps", self.gradient_steps)
        checks.positive_int("batch_size", self.batch_size)
        checks.positive("learning_rate", self.learning_rate)
        checks.non_negative_int("seed", self.seed)
        if self.trainer is not None:
            checks.one_of("trainer", self.trainer, TRAINERS)
        checks.positive_int("ensemble_seeds", self.ensemble_seeds)
        if self.ensemble_seeds > 1 and self.evaluation.episodes > 0:
            raise ValueError(
                "evaluation.episodes: an ensemble (ensemble_seeds > 1) has no one "
                "controller to test in closed loop; set evaluation.episodes=0"
            )
        check_controller(self.policy, self.sensors, trainer=self.trainer)


def check_controller(policy: PolicyConfig, sensors: SensorsConfig, *, trainer: str | None) -> None:
    """The controller ``policy`` on ``sensors`` can be built with its options and trained
    by ``trainer`` (``None``: its default); see ``pilerl.policies.check_controller_choice``."""
    if MISSING in (policy.name, sensors.s):
        return
    from pilerl.policies.config import check_controller_choice

    check_controller_choice(
        policy.name, sensors.s, sensors.s_prime, policy.options, trainer=trainer
    )


def register_configs() -> None:
    """Put the schemas in Hydra's ConfigStore (idempotent)."""
    store = ConfigStore.instance()
    store.store(name="scoop_schema", node=ScoopConfig)
    store.store(name="record_schema", node=RecordConfig)
    store.store(name="build_dataset_schema", node=BuildDatasetConfig)
    store.store(name="teleop_schema", node=TeleopConfig)
    store.store(name="train_bc_schema", node=TrainBCConfig)
    store.store(name="evaluate_schema", node=EvaluateConfig)
    store.store(group="policy", name="policy_schema", node=PolicyConfig)
    store.store(group="sensors", name="sensors_schema", node=SensorsConfig)
    store.store(group="env", name="env_schema", node=EnvConfig)
    store.store(group="dataset", name="dataset_schema", node=DatasetConfig)
    store.store(group="logger", name="logger_schema", node=LoggerConfig)
    # imported here: the RL and pipeline schemas build on this module
    from pilerl.rl.config import register_rl_configs

    from .pipeline import PipelineConfig

    register_rl_configs()
    store.store(name="pipeline_schema", node=PipelineConfig)
