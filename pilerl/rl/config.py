"""Typed configs of RL fine-tuning, registered in Hydra's ConfigStore.

``FinetuneConfig`` is the primary schema (``finetune_schema``); the ``algorithm`` group
holds ``PPOConfig`` (``ppo_schema``) or ``TD3BCConfig`` (``td3bc_schema``), chosen by its
``name``. Every field is checked in ``validate_finetune_config`` before any work starts,
so a bad value fails with the field's name, not deep inside a training loop.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING

from pilerl.config.schema import EnvConfig, LoggerConfig

ALGORITHMS = ("ppo", "td3bc")
REGULARIZERS = ("bc_demo", "frozen_actor", "none")
BACKENDS = ("single", "multiprocess", "ray")


@dataclass
class PPOConfig:
    """Clipped PPO (TorchRL ``ClipPPOLoss`` + ``GAE``) around the cloned actor.

    Attributes:
        name: ``ppo``.
        frames_per_batch: environment steps collected between updates.
        epochs: passes over each collected batch.
        minibatch_size: transitions per gradient step.
        actor_lr, critic_lr: Adam learning rates.
        gamma, lmbda: discount and GAE lambda (per control step, 0.05 s at 20 Hz).
        clip_epsilon: PPO ratio clip.
        entropy_coeff: entropy bonus weight.
        critic_coeff: value-loss weight.
        max_grad_norm: gradient clipping of each update.
        init_scale: initial exploration std around the cloned action (pre-tanh units).
        critic_hidden: hidden layer widths of the value network.
        critic_warmup_batches: first batches that train only the value network (the
            cloned actor is kept until its value is known).
        regularizer: ``bc_demo`` (MSE to demonstrated actions on demo batches),
            ``frozen_actor`` (MSE to the frozen cloned actor on the collected states) or
            ``none``.
        regularizer_weight: weight of that term in the actor loss (>= 0).
        regularizer_batch_size: demo transitions per gradient step (``bc_demo``).
    """

    name: str = "ppo"
    frames_per_batch: int = 2048
    epochs: int = 4
    minibatch_size: int = 256
    actor_lr: float = 3e-4
    critic_lr: float = 1e-3
    gamma: float = 0.995
    lmbda: float = 0.95
    clip_epsilon: float = 0.2
    entropy_coeff: float = 0.0
    critic_coeff: float = 1.0
    max_grad_norm: float = 1.0
    init_scale: float = 0.3
    critic_hidden: list[int] = field(default_factory=lambda: [64, 64])
    critic_warmup_batches: int = 2
    regularizer: str = "frozen_actor"
    regularizer_weight: float = 0.1
    regularizer_batch_size: int = 256


@dataclass
class TD3BCConfig:
    """TD3+BC (TorchRL ``TD3BCLoss``): twin Q, delayed actor, demos mixed into replay.

    Attributes:
        name: ``td3bc``.
        frames_per_batch: environment steps collected between update rounds.
        updates_per_batch: gradient steps per collected batch.
        batch_size: transitions per gradient step (demos + online).
        demo_fraction: share of each batch drawn from the demonstrations (0..1).
        buffer_size: online replay capacity [transitions].
        actor_lr, critic_lr: Adam learning rates.
        gamma: discount per control step.
        tau: soft target update rate.
        alpha: TD3+BC's Q weight (the BC term has weight 1; larger = less BC).
        policy_delay: critic updates per actor update.
        policy_noise, noise_clip: target policy smoothing noise.
        exploration_sigma: std of the Gaussian noise added to the action when collecting.
        critic_hidden: hidden widths of each Q network.
        critic_warmup_batches: first batches that train only the Q networks.
    """

    name: str = "td3bc"
    frames_per_batch: int = 1000
    updates_per_batch: int = 250
    batch_size: int = 256
    demo_fraction: float = 0.25
    buffer_size: int = 200_000
    actor_lr: float = 3e-5
    critic_lr: float = 3e-4
    gamma: float = 0.99
    tau: float = 0.005
    alpha: float = 2.5
    policy_delay: int = 2
    policy_noise: float = 0.1
    noise_clip: float = 0.3
    exploration_sigma: float = 0.1
    critic_hidden: list[int] = field(default_factory=lambda: [128, 128])
    critic_warmup_batches: int = 2


@dataclass
class CurriculumStage:
    """One curriculum stage: a mixture of conditions practised for some frames.

    Attributes:
        frames: environment steps in this stage.
        conditions: condition (or group: each member gets its weight) -> relative weight;
            each episode draws one condition.
    """

    frames: int = MISSING
    conditions: dict[str, float] = MISSING


@dataclass
class CurriculumConfig:
    """Stages practised in order (the ``curriculum`` group)."""

    name: str = "custom"
    stages: list[CurriculumStage] = MISSING


@dataclass
class CollectionConfig:
    """How experience is collected.

    Attributes:
        backend: ``single`` (TorchRL ``Collector`` in this process), ``multiprocess``
            (``MultiSyncCollector``, one env per worker process) or ``ray``
            (``pilerl.rl.ray_collection``).
        workers: collector processes (``multiprocess``, ``ray``).
        envs_per_worker: simulators each collector steps as one batched TorchRL env
            (``SimulatorBatchEnv``): TorchRL's per-step cost and the actor's forward pass
            are paid once for all of them (measured ~3x faster at 8 than at 1 on one
            core). With 1, each step also records ``success`` and the reward parts.
        ray_init_kwargs: keyword arguments of ``ray.init`` (``ray`` backend).
    """

    backend: str = "single"
    workers: int = 1
    envs_per_worker: int = 8
    ray_init_kwargs: dict[str, Any] = field(default_factory=dict)


@dataclass
class EvaluationConfig:
    """Closed-loop evaluation during and after fine-tuning (``pilerl.evaluation``).

    Attributes:
        groups: group name -> conditions (or groups) pooled into one success rate;
            empty: the simulator's declared groups, then each condition in no group on its
            own (the pile loader: ``winter`` = A-D, ``summer``).
        every_frames: evaluate every this many frames, and at frame 0 (0 = only before
            and after: no curve, ``best.pt`` is the last actor).
        episodes: episodes per condition in a periodic evaluation.
        final_episodes: episodes per condition before and after fine-tuning.
        seed: base seed of periodic evaluations.
        final_seed: base seed of the before/after evaluations (other starts than the
            periodic ones, which pick ``best.pt``).
        workers: evaluation processes.
        video: render one episode per group at each evaluation (mp4).
        video_conditions: the condition filmed for each group (its first if absent).
        confidence: level of the Wilson intervals.
    """

    groups: dict[str, list[str]] = field(default_factory=dict)
    every_frames: int = 20_000
    episodes: int = 5
    final_episodes: int = 10
    seed: int = 0
    final_seed: int = 7
    workers: int = 1
    video: bool = False
    video_conditions: dict[str, str] = field(default_factory=dict)
    confidence: float = 0.95


@dataclass
class FinetuneConfig:
    """The finetune recipe: RL fine-tuning of a cloned controller in the simulator.

    Attributes:
        checkpoint: the cloned actor (``best.pt`` of ``recipes/train_bc.py``).
        demos: dataset of demonstrations (``bc_demo`` regulariser, TD3+BC replay), or
            ``None``.
        env: simulator arguments; ``env.condition`` is replaced per episode by the
            curriculum's mixture.
        algorithm: ``PPOConfig`` or ``TD3BCConfig``.
        curriculum: condition mixtures and their frames.
        reward_weights: multiplier of each named reward part reported by the simulator
            in ``info`` (``reward_fill``, ``reward_success``...); the training reward is
            their weighted sum. Parts not named are left out; empty: every reward part the
            simulator declares, with weight 1.
        collection: collector backend and workers.
        evaluation: periodic and final closed-loop evaluation.
        seed: seeds torch, the collector envs and the replay sampling.
        logger: TorchRL metric logger (the ``logger`` group: csv, tensorboard, none).
        checkpoint_every_frames: write ``last.ckpt`` at least this often [frames].
        time_budget_minutes: stop collecting after this wall time [min] (0 = no limit),
            then evaluate and write the results as after the last frame.
        output_dir: run directory (resumed if it holds ``last.ckpt``).
    """

    checkpoint: str | None = None  # required: checked by validate_finetune_config
    demos: str | None = None
    env: EnvConfig = field(default_factory=EnvConfig)
    algorithm: Any = MISSING  # PPOConfig | TD3BCConfig, chosen by the algorithm group
    curriculum: CurriculumConfig = field(default_factory=CurriculumConfig)
    reward_weights: dict[str, float] = field(default_factory=dict)
    collection: CollectionConfig = field(default_factory=CollectionConfig)
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    seed: int = 0
    logger: LoggerConfig = field(default_factory=LoggerConfig)
    checkpoint_every_frames: int = 10_000
    time_budget_minutes: float = 0.0
    output_dir: str = MISSING

    def __post_init__(self) -> None:
        # the algorithm group fills ``algorithm``; a config built without one is checked
        # when it is finally used (``finetune`` validates again)
        if self.algorithm is not MISSING and self.algorithm != MISSING:
            validate_finetune_config(self, inputs_exist=False)
            # the simulator's words in place of empty defaults (see the attributes)
            _, self.evaluation.groups, self.reward_weights = _simulator_words(self)


def resolve_simulator_words(config: FinetuneConfig) -> FinetuneConfig:
    """``config`` with the simulator's words filled in: curriculum groups expanded to
    conditions, ``evaluation.groups`` and ``reward_weights`` defaulted from the simulator's
    declaration (see their attributes). Unknown names fail listing the known ones."""
    stages, groups, weights = _simulator_words(config)
    return dataclasses.replace(
        config,
        curriculum=dataclasses.replace(config.curriculum, stages=stages),
        evaluation=dataclasses.replace(config.evaluation, groups=groups),
        reward_weights=weights,
    )


def _simulator_words(
    config: FinetuneConfig,
) -> tuple[list[CurriculumStage], dict[str, list[str]], dict[str, float]]:
    plugin = config.env.plugin()
    stages = [
        dataclasses.replace(
            stage,
            conditions=plugin.resolve_mixture(
                stage.conditions, where=f"curriculum.stages[{i}].conditions"
            ),
        )
        for i, stage in enumerate(config.curriculum.stages)
    ]
    groups = {
        group: list(plugin.resolve_conditions(members, where=f"evaluation.groups.{group}"))
        for group, members in (config.evaluation.groups or plugin.pooled_groups()).items()
    }
    weights = dict(config.reward_weights) or dict.fromkeys(plugin.reward_parts, 1.0)
    unknown = sorted(set(weights) - set(plugin.reward_parts))
    if unknown:
        raise ValueError(
            f"reward_weights: simulator {plugin.name!r} reports no reward part(s) {unknown}; "
            f"its parts: {list(plugin.reward_parts)}"
        )
    return stages, groups, weights


def uses_demos(config: FinetuneConfig) -> bool:
    """Whether the learner reads the demonstrations (PPO's ``bc_demo`` regulariser, TD3+BC
    with ``demo_fraction > 0``); only then are they loaded."""
    algorithm = config.algorithm
    if config.demos is None:
        return False
    if isinstance(algorithm, PPOConfig):
        return algorithm.regularizer == "bc_demo"
    return algorithm.demo_fraction > 0


def _positive(where: str, value: float) -> None:
    if not (
        isinstance(value, (int, float))
        and not isinstance(value, bool)
        and math.isfinite(value)
        and value > 0
    ):
        raise ValueError(f"{where}: must be a finite number > 0, got {value!r}")


def _non_negative(where: str, value: float) -> None:
    if not (
        isinstance(value, (int, float))
        and not isinstance(value, bool)
        and math.isfinite(value)
        and value >= 0
    ):
        raise ValueError(f"{where}: must be a finite number >= 0, got {value!r}")


def validate_finetune_config(config: FinetuneConfig, *, inputs_exist: bool = True) -> None:
    """Raise ``ValueError`` (naming the field) for anything that cannot be trained.

    ``inputs_exist=False`` skips the checks that the checkpoint and demos exist (for a
    pipeline that validates its settings before the steps that write them).
    """
    algorithm = config.algorithm
    if not isinstance(algorithm, PPOConfig | TD3BCConfig):
        raise ValueError(
            f"algorithm: must be one of the algorithm group's configs {list(ALGORITHMS)}, "
            f"got {algorithm!r}"
        )
    if getattr(algorithm, "name", None) not in ALGORITHMS:
        raise ValueError(
            f"algorithm: unknown {getattr(algorithm, 'name', algorithm)!r}; "
            f"known: {list(ALGORITHMS)}"
        )
    if not config.checkpoint:
        raise ValueError(
            "checkpoint: required: a train_bc run directory or its best.pt "
            "(e.g. checkpoint=outputs/bc/dannet)"
        )
    if inputs_exist and not Path(config.checkpoint).is_file():
        raise FileNotFoundError(f"checkpoint: no such actor checkpoint {config.checkpoint!r}")
    if inputs_exist and uses_demos(config) and not Path(config.demos).is_dir():
        raise FileNotFoundError(f"demos: no such dataset directory {config.demos!r}")
    if isinstance(algorithm, PPOConfig):
        for name in ("frames_per_batch", "epochs", "minibatch_size", "regularizer_batch_size"):
            _positive(f"algorithm.{name}", getattr(algorithm, name))
        for name in ("actor_lr", "critic_lr", "clip_epsilon", "max_grad_norm", "init_scale"):
            _positive(f"algorithm.{name}", getattr(algorithm, name))
        for name in ("entropy_coeff", "critic_coeff", "regularizer_weight"):
            _non_negative(f"algorithm.{name}", getattr(algorithm, name))
        if not 0 <= algorithm.lmbda <= 1:
            raise ValueError(f"algorithm.lmbda: must lie in [0, 1], got {algorithm.lmbda}")
        if algorithm.clip_epsilon >= 1:
            raise ValueError(
                f"algorithm.clip_epsilon: must lie in (0, 1), got {algorithm.clip_epsilon}"
            )
        if algorithm.regularizer not in REGULARIZERS:
            raise ValueError(
                f"algorithm.regularizer: unknown {algorithm.regularizer!r}; "
                f"known: {list(REGULARIZERS)}"
            )
        if algorithm.regularizer == "bc_demo" and config.demos is None:
            raise ValueError("algorithm.regularizer 'bc_demo' needs demos: a dataset directory")
    else:
        for name in ("frames_per_batch", "updates_per_batch", "batch_size", "buffer_size"):
            _positive(f"algorithm.{name}", getattr(algorithm, name))
        for name in ("actor_lr", "critic_lr", "tau", "policy_delay"):
            _positive(f"algorithm.{name}", getattr(algorithm, name))
        for name in ("alpha", "policy_noise", "noise_clip", "exploration_sigma"):
            _non_negative(f"algorithm.{name}", getattr(algorithm, name))
        if algorithm.tau > 1:
            raise ValueError(f"algorithm.tau: must lie in (0, 1], got {algorithm.tau}")
        if algorithm.batch_size > algorithm.buffer_size:
            raise ValueError(
                f"algorithm.batch_size ({algorithm.batch_size}) exceeds algorithm.buffer_size "
                f"({algorithm.buffer_size})"
            )
        if not 0 <= algorithm.demo_fraction <= 1:
            raise ValueError(
                f"algorithm.demo_fraction: must lie in [0, 1], got {algorithm.demo_fraction}"
            )
        if algorithm.demo_fraction > 0:
            if config.demos is None:
                raise ValueError("algorithm.demo_fraction > 0 needs demos: a dataset directory")
            if any(w != 1.0 for w in config.reward_weights.values()):
                raise ValueError(
                    "reward_weights: demonstrations carry the simulator's unweighted reward; "
                    "TD3+BC with demo_fraction > 0 needs every weight = 1.0, got "
                    f"{dict(config.reward_weights)}"
                )
    if not algorithm.critic_hidden or not all(
        isinstance(w, int) and not isinstance(w, bool) and w >= 1 for w in algorithm.critic_hidden
    ):
        raise ValueError(
            f"algorithm.critic_hidden: must list layer widths >= 1, got {algorithm.critic_hidden}"
        )
    _non_negative("algorithm.critic_warmup_batches", algorithm.critic_warmup_batches)
    if not 0 < algorithm.gamma <= 1:
        raise ValueError(f"algorithm.gamma: must lie in (0, 1], got {algorithm.gamma}")
    if not config.curriculum.stages:
        raise ValueError("curriculum.stages: need at least one stage")
    for i, stage in enumerate(config.curriculum.stages):
        _positive(f"curriculum.stages[{i}].frames", stage.frames)
        if not stage.conditions:
            raise ValueError(f"curriculum.stages[{i}].conditions: empty mixture")
        for condition, weight in stage.conditions.items():
            _non_negative(f"curriculum.stages[{i}].conditions.{condition}", weight)
        if sum(stage.conditions.values()) <= 0:
            raise ValueError(f"curriculum.stages[{i}].conditions: weights sum to 0")
    for part, weight in config.reward_weights.items():
        if not (isinstance(weight, (int, float)) and math.isfinite(weight)):
            raise ValueError(f"reward_weights.{part}: must be finite, got {weight!r}")
        if weight < 0:
            raise ValueError(
                f"reward_weights.{part}: must be >= 0 (the simulator signs its parts), got {weight}"
            )
    if config.collection.backend not in BACKENDS:
        raise ValueError(
            f"collection.backend: unknown {config.collection.backend!r}; known: {list(BACKENDS)}"
        )
    _positive("collection.workers", config.collection.workers)
    _positive("collection.envs_per_worker", config.collection.envs_per_worker)
    if (
        config.collection.backend == "ray"
        and algorithm.frames_per_batch % config.collection.workers
    ):
        raise ValueError(
            f"algorithm.frames_per_batch ({algorithm.frames_per_batch}) must be a multiple of "
            f"collection.workers ({config.collection.workers}) for the ray backend (each "
            "remote collector fills an equal share of a batch)"
        )
    evaluation = config.evaluation
    if not all(evaluation.groups.values()):
        raise ValueError(f"evaluation.groups: each group needs conditions, got {evaluation.groups}")
    _non_negative("evaluation.every_frames", evaluation.every_frames)
    _positive("evaluation.episodes", evaluation.episodes)
    _positive("evaluation.final_episodes", evaluation.final_episodes)
    _positive("evaluation.workers", evaluation.workers)
    if not 0 < evaluation.confidence < 1:
        raise ValueError(f"evaluation.confidence: must lie in (0, 1), got {evaluation.confidence}")
    _, groups, _ = _simulator_words(config)
    unknown = sorted(set(evaluation.video_conditions) - set(groups))
    if unknown:
        raise ValueError(
            f"evaluation.video_conditions: groups {unknown} are not in evaluation.groups "
            f"{sorted(groups)}"
        )
    _non_negative("evaluation.seed", evaluation.seed)
    _non_negative("evaluation.final_seed", evaluation.final_seed)
    _non_negative("seed", config.seed)
    _positive("checkpoint_every_frames", config.checkpoint_every_frames)
    _non_negative("time_budget_minutes", config.time_budget_minutes)


def register_rl_configs() -> None:
    """Put the fine-tuning schemas in Hydra's ConfigStore (idempotent)."""
    store = ConfigStore.instance()
    store.store(name="finetune_schema", node=FinetuneConfig)
    store.store(group="algorithm", name="ppo_schema", node=PPOConfig)
    store.store(group="algorithm", name="td3bc_schema", node=TD3BCConfig)
    store.store(group="curriculum", name="curriculum_schema", node=CurriculumConfig)
