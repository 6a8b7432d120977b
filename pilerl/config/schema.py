"""Typed config schemas registered in Hydra's ConfigStore.

The YAML files under conf/ extend these schemas, so a wrong type or an unknown key fails
when Hydra composes the config, before any work starts. Recipes turn a config into plain
library arguments once, at their boundary (``EnvConfig.make_kwargs``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING

from pilerl.operators import OperatorStyle
from pilerl.sim.settings import EnvConfig, register_env_configs

from . import checks

CONF_ENV = Path(__file__).resolve().parents[2] / "conf" / "env"  # this checkout's env YAMLs


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
        record_hz: sampling (= control) rate of the recording [Hz] (the paper: 500); it
            replaces ``env.control_hz`` (the simulator must declare that option).
        expert: options of the simulator's scripted expert for drawn operator styles
            (the pile loader's: ``trigger_sensor``, ``mistake_rate``); ``{}``: its defaults.
        workers: recording processes.
        out_dir: dataset directory; an existing one is resumed.
    """

    env: EnvConfig = field(default_factory=EnvConfig)
    n_episodes: int = 72
    seed: int = 0
    record_hz: float = 500.0
    expert: dict[str, Any] = field(default_factory=dict)
    workers: int = 2
    out_dir: str = MISSING

    def __post_init__(self) -> None:
        checks.positive_int("n_episodes", self.n_episodes)
        checks.non_negative_int("seed", self.seed)
        checks.positive("record_hz", self.record_hz)
        try:
            self.env.make_kwargs(control_hz=self.record_hz)
        except ValueError as error:
            raise ValueError(f"record_hz ({self.record_hz}): {error}") from None
        self.env.plugin().check_expert_options(self.expert, where="expert", drawn=True)
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
        conditions: conditions and condition groups of the simulator to test in (``all``:
            every condition; the pile loader's ``winter``: A-D); a declared group with two
            or more tested conditions is also pooled.
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

    conditions: list[str] = field(default_factory=lambda: ["all"])
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
        checks.render_size("evaluation.", self.render_width, self.render_height)
        checks.video_choice("evaluation.videos", self.videos)

    def condition_names(self, env: EnvConfig) -> tuple[str, ...]:
        """The conditions tested in ``env``'s simulator (groups expanded); checks that
        ``video_conditions`` are among them."""
        conditions = env.plugin().resolve_conditions(self.conditions, where="evaluation.conditions")
        unknown = [c for c in self.video_conditions or () if c not in conditions]
        if unknown:
            raise ValueError(
                f"evaluation.video_conditions: {unknown} are not evaluated; "
                f"evaluation.conditions are {list(conditions)}"
            )
        return conditions

    def plan(self, env: EnvConfig):
        """The ``EvaluationPlan`` of this config in ``env`` (its condition is replaced)."""
        from pilerl.evaluation.evaluator import EvaluationPlan

        kwargs = env.make_kwargs()
        kwargs.pop("condition")
        conditions = self.condition_names(env)
        return EvaluationPlan(env.simulator, kwargs, conditions, self.episodes, seed=self.seed)


@dataclass
class EvaluateConfig:
    """The evaluate recipe: a controller tested in closed loop.

    Attributes:
        env: simulator arguments (``env.condition`` is replaced by each evaluated one).
        checkpoint: a saved actor (``best.pt`` of train_bc or finetune); ``None`` evaluates
            the simulator's nominal scripted expert.
        name: the controller's name in plots and tables (default: from the checkpoint).
        expert: options of the nominal scripted expert (used when ``checkpoint`` is
            ``None``; the pile loader's: ``OperatorStyle`` fields); ``{}``: its defaults.
        evaluation: conditions, episodes, seed, workers, videos.
    """

    env: EnvConfig = field(default_factory=EnvConfig)
    checkpoint: str | None = None
    name: str | None = None
    expert: dict[str, Any] = field(default_factory=dict)
    evaluation: ClosedLoopConfig = field(default_factory=ClosedLoopConfig)
    output_dir: str = MISSING

    def __post_init__(self) -> None:
        if self.checkpoint is not None:
            checks.path("checkpoint", self.checkpoint)
        if self.name is not None:
            checks.name("name", self.name)
        self.evaluation.condition_names(self.env)
        if self.checkpoint is None:
            self.env.plugin().check_expert_options(self.expert, where="expert", drawn=False)


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
        self.evaluation.condition_names(self.env)
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
    register_env_configs(yaml_names={p.stem for p in CONF_ENV.glob("*.yaml")})
    store.store(group="dataset", name="dataset_schema", node=DatasetConfig)
    store.store(group="logger", name="logger_schema", node=LoggerConfig)
    # imported here: the RL and pipeline schemas build on this module
    from pilerl.rl.config import register_rl_configs

    from .pipeline import PipelineConfig

    register_rl_configs()
    store.store(name="pipeline_schema", node=PipelineConfig)
