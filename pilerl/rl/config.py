"""The RL room's settings: fine-tuning a cloned controller (``FinetuneConfig``).

``FinetuneConfig`` is the finetune recipe's primary schema and ``pilerl.rl.finetune``'s
argument; its ``algorithm`` node is one of the learners registered in ``ALGORITHMS``
(``PPOConfig``, ``TD3BCConfig``: the ``algorithm`` config group), both built on
``LearnerConfig``. Every field is checked in its dataclass's ``__post_init__``, so a bad
value fails with the field's name when the config is built, not deep inside a training
loop; ``FinetuneConfig.check_inputs`` then checks that the checkpoint and demonstrations
exist (a pipeline writes them after building its config).
"""

from __future__ import annotations

import dataclasses
import functools
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from omegaconf import MISSING, OmegaConf

from pilerl import checks
from pilerl.loggers import LoggerConfig
from pilerl.registry import Registry
from pilerl.sim.registry import make_gym_env
from pilerl.sim.settings import EnvConfig

REGULARIZERS = ("bc_demo", "frozen_actor", "none")
BACKENDS = ("single", "multiprocess", "ray")


@dataclass
class LearnerConfig:
    """What every learner of the ``algorithm`` group has (PPO, TD3+BC).

    Attributes:
        name: the registered algorithm (``ALGORITHMS``).
        frames_per_batch: environment steps collected between updates.
        actor_lr, critic_lr: Adam learning rates.
        gamma: discount per control step (0.05 s at 20 Hz), in (0, 1].
        critic_hidden: hidden layer widths of the value / each Q network.
        critic_warmup_batches: first batches that train only the critic (the cloned actor
            is kept until its value is known).
    """

    name: str = MISSING
    frames_per_batch: int = 2048
    actor_lr: float = 3e-4
    critic_lr: float = 1e-3
    gamma: float = 0.99
    critic_hidden: list[int] = field(default_factory=lambda: [64, 64])
    critic_warmup_batches: int = 2

    def __post_init__(self) -> None:
        checks.positive_int("algorithm.frames_per_batch", self.frames_per_batch)
        checks.positive("algorithm.actor_lr", self.actor_lr)
        checks.positive("algorithm.critic_lr", self.critic_lr)
        if not (isinstance(self.gamma, int | float) and 0 < self.gamma <= 1):
            raise ValueError(f"algorithm.gamma: must lie in (0, 1], got {self.gamma}")
        if not self.critic_hidden or not all(
            isinstance(w, int) and not isinstance(w, bool) and w >= 1 for w in self.critic_hidden
        ):
            raise ValueError(
                f"algorithm.critic_hidden: must list layer widths >= 1, got {self.critic_hidden}"
            )
        checks.non_negative_int("algorithm.critic_warmup_batches", self.critic_warmup_batches)


@dataclass
class PPOConfig(LearnerConfig):
    """Clipped PPO (TorchRL ``ClipPPOLoss`` + ``GAE``) around the cloned actor.

    Attributes:
        name: ``ppo``.
        gamma: 0.995 per control step: a horizon of ~10 s at 20 Hz.
        epochs: passes over each collected batch.
        minibatch_size: transitions per gradient step.
        lmbda: GAE lambda, in [0, 1].
        clip_epsilon: PPO ratio clip, in (0, 1).
        entropy_coeff: entropy bonus weight.
        critic_coeff: value-loss weight.
        max_grad_norm: gradient clipping of each update.
        init_scale: initial exploration std around the cloned action (pre-tanh units).
        regularizer: ``bc_demo`` (MSE to demonstrated actions on demo batches),
            ``frozen_actor`` (MSE to the frozen cloned actor on the collected states) or
            ``none``.
        regularizer_weight: weight of that term in the actor loss (>= 0).
        regularizer_batch_size: demo transitions per gradient step (``bc_demo``).
        (The rest: ``LearnerConfig``.)
    """

    name: str = "ppo"
    gamma: float = 0.995
    epochs: int = 4
    minibatch_size: int = 256
    lmbda: float = 0.95
    clip_epsilon: float = 0.2
    entropy_coeff: float = 0.0
    critic_coeff: float = 1.0
    max_grad_norm: float = 1.0
    init_scale: float = 0.3
    regularizer: str = "frozen_actor"
    regularizer_weight: float = 0.1
    regularizer_batch_size: int = 256

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("epochs", "minibatch_size", "regularizer_batch_size"):
            checks.positive_int(f"algorithm.{name}", getattr(self, name))
        for name in ("clip_epsilon", "max_grad_norm", "init_scale"):
            checks.positive(f"algorithm.{name}", getattr(self, name))
        for name in ("entropy_coeff", "critic_coeff", "regularizer_weight"):
            checks.non_negative(f"algorithm.{name}", getattr(self, name))
        if not 0 <= self.lmbda <= 1:
            raise ValueError(f"algorithm.lmbda: must lie in [0, 1], got {self.lmbda}")
        if self.clip_epsilon >= 1:
            raise ValueError(f"algorithm.clip_epsilon: must lie in (0, 1), got {self.clip_epsilon}")
        checks.one_of("algorithm.regularizer", self.regularizer, REGULARIZERS)

    def uses_demos(self) -> bool:
        """Whether this learner reads demonstrations (the ``bc_demo`` regulariser)."""
        return self.regularizer == "bc_demo"


@dataclass
class TD3BCConfig(LearnerConfig):
    """TD3+BC (TorchRL ``TD3BCLoss``): twin Q, delayed actor, demos mixed into replay.

    Attributes:
        name: ``td3bc``.
        frames_per_batch: environment steps collected between update rounds.
        updates_per_batch: gradient steps per collected batch.
        batch_size: transitions per gradient step (demos + online).
        demo_fraction: share of each batch drawn from the demonstrations (0..1).
        buffer_size: online replay capacity [transitions].
        tau: soft target update rate, in (0, 1].
        alpha: TD3+BC's Q weight (the BC term has weight 1; larger = less BC).
        policy_delay: critic updates per actor update.
        policy_noise, noise_clip: target policy smoothing noise.
        exploration_sigma: std of the Gaussian noise added to the action when collecting.
        (The rest: ``LearnerConfig``.)
    """

    name: str = "td3bc"
    frames_per_batch: int = 1000
    actor_lr: float = 3e-5
    critic_lr: float = 3e-4
    critic_hidden: list[int] = field(default_factory=lambda: [128, 128])
    updates_per_batch: int = 250
    batch_size: int = 256
    demo_fraction: float = 0.25
    buffer_size: int = 200_000
    tau: float = 0.005
    alpha: float = 2.5
    policy_delay: int = 2
    policy_noise: float = 0.1
    noise_clip: float = 0.3
    exploration_sigma: float = 0.1

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("updates_per_batch", "batch_size", "buffer_size", "policy_delay"):
            checks.positive_int(f"algorithm.{name}", getattr(self, name))
        checks.positive("algorithm.tau", self.tau)
        for name in ("alpha", "policy_noise", "noise_clip", "exploration_sigma"):
            checks.non_negative(f"algorithm.{name}", getattr(self, name))
        if self.tau > 1:
            raise ValueError(f"algorithm.tau: must lie in (0, 1], got {self.tau}")
        if self.batch_size > self.buffer_size:
            raise ValueError(
                f"algorithm.batch_size ({self.batch_size}) exceeds algorithm.buffer_size "
                f"({self.buffer_size})"
            )
        if not (isinstance(self.demo_fraction, int | float) and 0 <= self.demo_fraction <= 1):
            raise ValueError(
                f"algorithm.demo_fraction: must lie in [0, 1], got {self.demo_fraction}"
            )

    def uses_demos(self) -> bool:
        """Whether this learner reads demonstrations (``demo_fraction > 0``)."""
        return self.demo_fraction > 0


@dataclass
class RLPDConfig(LearnerConfig):
    """Off-policy fine-tuning with demonstrations in the replay (RLPD-style), optionally as
    residual RL on the frozen cloned actor (``pilerl.rl.rlpd``, ``pilerl.rl.residual``).

    TorchRL ``TD3Loss`` over an ensemble of LayerNorm Q networks, TorchRL
    ``OfflineToOnlineReplayBuffer`` drawing ``demo_fraction`` of every batch from the
    demonstrations (0.5: RLPD's symmetric sampling), ``utd_ratio`` gradient steps per
    collected frame.

    Attributes:
        name: ``rlpd``.
        gamma: 0.997 per control step: the success bonus at the end of a 10-20 s scoop
            must reach the critic (0.997^300 = 0.41; with 0.99, 0.05, both off-policy
            learners were measured to learn to end the scoop early, empty).
        frames_per_batch: environment steps collected between update rounds.
        utd_ratio: critic gradient steps per collected frame (update-to-data ratio, > 0).
        batch_size: transitions per gradient step (demos + online).
        demo_fraction: share of each batch drawn from the demonstrations, in (0, 1);
            0.5 is RLPD's symmetric sampling.
        critic_ensemble: Q networks in the ensemble (>= 2); the TD target is their
            minimum (TorchRL ``TD3Loss``), the actor follows the first.
        critic_layer_norm: LayerNorm after each hidden layer of every Q network (RLPD).
        buffer_size: online replay capacity [transitions].
        tau: soft target update rate, in (0, 1].
        policy_delay: critic updates per actor update.
        policy_noise, noise_clip: target policy smoothing noise (action units).
        exploration_sigma: std of the Gaussian noise added to the action when collecting.
        residual: learn a residual actor added to the frozen clone's action (it starts
            at zero, so the first actor is exactly the clone) instead of the clone's weights.
        residual_scale: the largest correction the residual may add to each control
            (``scale * tanh(.)``, action units in [-1, 1]).
        residual_hidden: hidden layer widths of the residual actor.
        critic_warmup_batches: first batches (the clone's own rollouts, with exploration
            noise; 8 x 500 frames, about 8-10 scoops) that train only the critics, before
            any actor update.
        warmup_utd_ratio: critic gradient steps per collected frame during the warm-up.
        calibrated_critic: raise the TD target of every demonstration transition to at
            least its Monte-Carlo discounted return (``pilerl.rl.calibration``, after
            Cal-QL); false keeps plain RLPD.
        (The rest: ``LearnerConfig``.)
    """

    name: str = "rlpd"
    frames_per_batch: int = 500
    actor_lr: float = 1e-4
    critic_lr: float = 3e-4
    gamma: float = 0.997
    critic_hidden: list[int] = field(default_factory=lambda: [128, 128])
    critic_warmup_batches: int = 8
    utd_ratio: float = 0.5
    batch_size: int = 256
    demo_fraction: float = 0.5
    critic_ensemble: int = 4
    critic_layer_norm: bool = True
    buffer_size: int = 200_000
    tau: float = 0.005
    policy_delay: int = 2
    policy_noise: float = 0.1
    noise_clip: float = 0.3
    exploration_sigma: float = 0.1
    residual: bool = False
    residual_scale: float = 0.2
    residual_hidden: list[int] = field(default_factory=lambda: [64, 64])
    warmup_utd_ratio: float = 1.0
    calibrated_critic: bool = False

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.calibrated_critic, bool):
            raise ValueError(
                f"algorithm.calibrated_critic: must be true or false, "
                f"got {self.calibrated_critic!r}"
            )
        for name in ("batch_size", "buffer_size", "policy_delay"):
            checks.positive_int(f"algorithm.{name}", getattr(self, name))
        for name in ("utd_ratio", "warmup_utd_ratio", "tau", "residual_scale"):
            checks.positive(f"algorithm.{name}", getattr(self, name))
        for name in ("policy_noise", "noise_clip", "exploration_sigma"):
            checks.non_negative(f"algorithm.{name}", getattr(self, name))
        if self.tau > 1:
            raise ValueError(f"algorithm.tau: must lie in (0, 1], got {self.tau}")
        if not (isinstance(self.demo_fraction, int | float) and 0 < self.demo_fraction < 1):
            raise ValueError(
                f"algorithm.demo_fraction: must lie in (0, 1) (0.5: symmetric sampling), "
                f"got {self.demo_fraction}"
            )
        if not isinstance(self.critic_ensemble, int) or self.critic_ensemble < 2:
            raise ValueError(
                f"algorithm.critic_ensemble: must be an integer >= 2, got {self.critic_ensemble}"
            )
        if self.batch_size > self.buffer_size:
            raise ValueError(
                f"algorithm.batch_size ({self.batch_size}) exceeds algorithm.buffer_size "
                f"({self.buffer_size})"
            )
        if not self.residual_hidden or not all(
            isinstance(w, int) and not isinstance(w, bool) and w >= 1 for w in self.residual_hidden
        ):
            raise ValueError(
                f"algorithm.residual_hidden: must list layer widths >= 1, "
                f"got {self.residual_hidden}"
            )
        if self.residual_scale > 2:
            raise ValueError(
                f"algorithm.residual_scale: at most 2 (the action range), got {self.residual_scale}"
            )

    def uses_demos(self) -> bool:
        """Always: half of every batch (``demo_fraction``) comes from the demonstrations."""
        return True

    def updates_for(self, frames: int, *, warmup: bool) -> int:
        """Critic gradient steps for a batch of ``frames`` (at least one)."""
        ratio = self.warmup_utd_ratio if warmup else self.utd_ratio
        return max(1, round(ratio * frames))


# the ``algorithm`` group: name -> its settings (conf/algorithm/<name>.yaml extends them)
ALGORITHMS: Registry[type[LearnerConfig]] = Registry(
    "algorithm", {"ppo": PPOConfig, "td3bc": TD3BCConfig, "rlpd": RLPDConfig}
)


@dataclass
class CurriculumStage:
    """One curriculum stage: a mixture of conditions practised for some frames.

    Attributes:
        frames: environment steps in this stage.
        conditions: condition (or group: each member gets its weight) -> relative weight;
            each episode draws one condition. Empty: the simulator's declared
            ``curriculum`` (the pile loader: winter A-D and summer; others by default:
            every condition), so ``curriculum=default`` works with any simulator.
    """

    frames: int = MISSING
    conditions: dict[str, float] = MISSING


@dataclass
class CurriculumConfig:
    """Stages practised in order (the ``curriculum`` group)."""

    name: str = "custom"
    stages: list[CurriculumStage] = MISSING

    def __post_init__(self) -> None:
        if self.stages == MISSING:
            return  # the schema itself; a curriculum group choice fills the stages
        if not self.stages:
            raise ValueError("curriculum.stages: need at least one stage")
        for i, stage in enumerate(self.stages):
            checks.positive(f"curriculum.stages[{i}].frames", stage.frames)
            for condition, weight in stage.conditions.items():
                checks.non_negative(f"curriculum.stages[{i}].conditions.{condition}", weight)
            if stage.conditions and sum(stage.conditions.values()) <= 0:
                raise ValueError(f"curriculum.stages[{i}].conditions: weights sum to 0")


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
        env_variants: simulator options that the simulators of each collector take in
            turn (simulator ``i`` gets ``env`` updated by variant ``i mod n``), e.g. a second
            soil model, so that training sees both (``envs_per_worker`` must be a multiple
            of their number). Empty: every simulator is ``env``. Evaluations use ``env``
            (docs/finetuning.md, "Training on several soil models").
    """

    backend: str = "single"
    workers: int = 1
    envs_per_worker: int = 8
    ray_init_kwargs: dict[str, Any] = field(default_factory=dict)
    env_variants: list[dict[str, Any]] = field(default_factory=list)

    def __post_init__(self) -> None:
        checks.one_of("collection.backend", self.backend, BACKENDS)
        checks.positive_int("collection.workers", self.workers)
        checks.positive_int("collection.envs_per_worker", self.envs_per_worker)
        if self.env_variants and self.envs_per_worker % len(self.env_variants):
            raise ValueError(
                f"collection.env_variants: collection.envs_per_worker ({self.envs_per_worker}) "
                f"must be a multiple of their number ({len(self.env_variants)})"
            )
        for i, variant in enumerate(self.env_variants):
            if "condition" in variant:
                raise ValueError(
                    f"collection.env_variants[{i}]: may not set condition (the curriculum "
                    "chooses the conditions)"
                )
            if "control_hz" in variant:
                raise ValueError(
                    f"collection.env_variants[{i}]: may not set control_hz (the simulators of "
                    "a collector step together, one control period)"
                )


@dataclass
class EvaluationConfig:
    """Closed-loop evaluation during and after fine-tuning (``pilerl.evaluation``).

    Attributes:
        groups: group name -> conditions (or groups) pooled into one success rate;
            empty: the simulator's declared groups, then each condition in no group on its
            own (the pile loader: ``winter`` = A-D, ``summer``).
        every_frames: evaluate every this many frames, and at frame 0 (0 = only before
            and after: no curve, ``best.pt`` is the last actor).
        episodes: episodes per condition in a periodic evaluation (picks ``best.pt``).
        final_episodes: episodes per condition before and after fine-tuning.
        seed: base seed of periodic evaluations.
        final_seed: base seed of the before/after evaluations (other starts than the
            periodic ones, which pick ``best.pt``).
        workers: evaluation processes.
        video: render one episode per group at each evaluation (mp4).
        video_conditions: the condition filmed for each group (its first if absent).
        confidence: level of the Wilson intervals.
        at_scoops: also evaluate as soon as this many training scoops (episodes) have
            ended, for each number listed (increasing; the sample-efficiency benchmark's
            points). Evaluation episodes are not counted as scoops.
        cross_check_env: simulator options changed for a second before / after
            evaluation at the end (the cloned actor and ``best.pt``, ``final_episodes``
            per condition, ``final_seed``), e.g. another soil model:
            ``{soil: heightfield, soil_options: {intake: mouth, body_resistance: true}}``.
            A gain that does not carry over to it was learned from how the simulator
            models the task, not from the task (docs/finetuning.md). Empty: none.
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
    at_scoops: list[int] = field(default_factory=list)
    cross_check_env: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if "condition" in self.cross_check_env:
            raise ValueError(
                "evaluation.cross_check_env: may not set condition (the evaluation groups "
                "choose the conditions)"
            )
        for i, scoops in enumerate(self.at_scoops):
            checks.positive_int(f"evaluation.at_scoops[{i}]", scoops)
        if list(self.at_scoops) != sorted(set(self.at_scoops)):
            raise ValueError(
                f"evaluation.at_scoops: must increase strictly, got {list(self.at_scoops)}"
            )
        if not all(self.groups.values()):
            raise ValueError(f"evaluation.groups: each group needs conditions, got {self.groups}")
        checks.non_negative_int("evaluation.every_frames", self.every_frames)
        checks.positive_int("evaluation.episodes", self.episodes)
        checks.positive_int("evaluation.final_episodes", self.final_episodes)
        checks.positive_int("evaluation.workers", self.workers)
        if not (isinstance(self.confidence, int | float) and 0 < self.confidence < 1):
            raise ValueError(f"evaluation.confidence: must lie in (0, 1), got {self.confidence}")
        checks.non_negative_int("evaluation.seed", self.seed)
        checks.non_negative_int("evaluation.final_seed", self.final_seed)


@dataclass
class FinetuneConfig:
    """The finetune recipe: RL fine-tuning of a cloned controller in the simulator.

    Attributes:
        checkpoint: the cloned actor (``best.pt`` of ``recipes/train_bc.py``, or its run
            directory); required.
        demos: dataset of demonstrations (``bc_demo`` regulariser, TD3+BC replay), or
            ``None``.
        env: simulator arguments; ``env.condition`` is replaced per episode by the
            curriculum's mixture.
        algorithm: a registered learner's settings (``ALGORITHMS``: ``PPOConfig`` or
            ``TD3BCConfig``), chosen by the ``algorithm`` group.
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
        time_budget_minutes: stop collecting after this wall time [min] (0 = no limit:
            run the whole curriculum), then evaluate and write the results as after the
            last frame.
        output_dir: run directory (resumed if it holds ``last.ckpt``).
        max_scoops: stop collecting once this many training scoops (episodes) have ended
            (0 = no limit); the scoop budget of ``benchmarks/sample_efficiency.py``.
    """

    checkpoint: str | None = None
    demos: str | None = None
    env: EnvConfig = field(default_factory=EnvConfig)
    algorithm: Any = MISSING  # a LearnerConfig, chosen by the algorithm group
    curriculum: CurriculumConfig = field(default_factory=CurriculumConfig)
    reward_weights: dict[str, float] = field(default_factory=dict)
    collection: CollectionConfig = field(default_factory=CollectionConfig)
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    seed: int = 0
    logger: LoggerConfig = field(default_factory=LoggerConfig)
    checkpoint_every_frames: int = 10_000
    time_budget_minutes: float = 0.0
    output_dir: str = MISSING
    max_scoops: int = 0

    def __post_init__(self) -> None:
        checks.non_negative_int("max_scoops", self.max_scoops)
        for part, weight in self.reward_weights.items():
            checks.finite(f"reward_weights.{part}", weight)
            if weight < 0:
                raise ValueError(
                    f"reward_weights.{part}: must be >= 0 (the simulator signs its parts), "
                    f"got {weight}"
                )
        checks.non_negative_int("seed", self.seed)
        checks.positive_int("checkpoint_every_frames", self.checkpoint_every_frames)
        checks.non_negative("time_budget_minutes", self.time_budget_minutes)
        if self.algorithm is MISSING or self.algorithm == MISSING:
            return  # the schema itself: the algorithm group fills it
        self._check_algorithm()
        # the simulator's words in place of empty defaults (see the attributes)
        _, self.evaluation.groups, self.reward_weights = _simulator_words(self)
        if self.evaluation.cross_check_env:
            cross_check_kwargs(self, build=True)  # the simulator takes these options
        variant_kwargs(self, build=True)
        unknown = sorted(set(self.evaluation.video_conditions) - set(self.evaluation.groups))
        if unknown:
            raise ValueError(
                f"evaluation.video_conditions: groups {unknown} are not in evaluation.groups "
                f"{sorted(self.evaluation.groups)}"
            )

    def _check_algorithm(self) -> None:
        """The learner is registered and has what it needs from the rest of the config."""
        algorithm = self.algorithm
        if not isinstance(algorithm, LearnerConfig):
            raise ValueError(
                f"algorithm: must be one of the algorithm group's configs "
                f"{ALGORITHMS.names()}, got {algorithm!r}"
            )
        ALGORITHMS.check("algorithm", algorithm.name)
        if not isinstance(algorithm, ALGORITHMS[algorithm.name]):
            raise ValueError(
                f"algorithm: {algorithm.name!r} names {ALGORITHMS[algorithm.name].__name__}, "
                f"got a {type(algorithm).__name__}"
            )
        if not self.checkpoint:
            raise ValueError(
                "checkpoint: required: a train_bc run directory or its best.pt "
                "(e.g. checkpoint=outputs/bc/dannet)"
            )
        if isinstance(algorithm, PPOConfig):
            if algorithm.regularizer == "bc_demo" and self.demos is None:
                raise ValueError("algorithm.regularizer 'bc_demo' needs demos: a dataset directory")
        elif isinstance(algorithm, TD3BCConfig | RLPDConfig) and algorithm.demo_fraction > 0:
            if self.demos is None:
                raise ValueError("algorithm.demo_fraction > 0 needs demos: a dataset directory")
            if any(w != 1.0 for w in self.reward_weights.values()):
                raise ValueError(
                    "reward_weights: demonstrations carry the simulator's unweighted reward; "
                    f"{algorithm.name} with demo_fraction > 0 needs every weight = 1.0, got "
                    f"{dict(self.reward_weights)}"
                )
        workers = self.collection.workers
        if self.collection.backend == "ray" and algorithm.frames_per_batch % workers:
            raise ValueError(
                f"algorithm.frames_per_batch ({algorithm.frames_per_batch}) must be a multiple "
                f"of collection.workers ({self.collection.workers}) for the ray backend (each "
                "remote collector fills an equal share of a batch)"
            )

    def check_inputs(self) -> None:
        """``FileNotFoundError`` unless the checkpoint exists, and the demonstrations too
        if the learner reads them (PPO with the ``frozen_actor`` or no regulariser, and
        TD3+BC with ``demo_fraction`` 0, need none, whatever ``demos`` says)."""
        if not Path(self.checkpoint).is_file():
            raise FileNotFoundError(f"checkpoint: no such actor checkpoint {self.checkpoint!r}")
        if uses_demos(self) and not Path(self.demos).is_dir():
            raise FileNotFoundError(f"demos: no such dataset directory {self.demos!r}")


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
                stage.conditions or plugin.curriculum, where=f"curriculum.stages[{i}].conditions"
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
    return config.demos is not None and config.algorithm.uses_demos()


def cross_check_kwargs(config: FinetuneConfig, *, build: bool = False) -> dict[str, Any]:
    """The simulator's keyword arguments for the cross-check evaluation: ``config.env``'s
    with ``evaluation.cross_check_env`` applied (and no condition); an unknown option or a
    bad value fails naming ``evaluation.cross_check_env``. ``build``: also build the
    simulator once (a few tens of ms), so that the values only the simulator checks (its
    soil model's options) fail now, not after training."""
    return _env_with(
        config, config.evaluation.cross_check_env, "evaluation.cross_check_env", build=build
    )


def variant_kwargs(config: FinetuneConfig, *, build: bool = False) -> list[dict[str, Any]]:
    """The simulator's keyword arguments of each ``collection.env_variants`` entry
    (``config.env``'s updated by the variant, no condition), checked as
    ``cross_check_kwargs`` checks its own."""
    return [
        _env_with(config, variant, f"collection.env_variants[{i}]", build=build)
        for i, variant in enumerate(config.collection.env_variants)
    ]


def _env_with(
    config: FinetuneConfig, overrides: Mapping, where: str, *, build: bool
) -> dict[str, Any]:
    try:
        kwargs = config.env.make_kwargs(**plain_mapping(overrides))
        if build:
            _check_builds(config.env.simulator, json.dumps(kwargs, sort_keys=True, default=list))
    except (TypeError, ValueError) as error:
        raise ValueError(f"{where}: {error}") from None
    kwargs.pop("condition")
    return kwargs


@functools.lru_cache(maxsize=64)
def _check_builds(simulator: str, kwargs_json: str) -> None:
    """Build the simulator once with these keyword arguments (JSON) and close it: a config
    is built several times (Hydra, ``dataclasses.replace``), the simulator checked once per
    process (a particle pile takes seconds to build)."""
    kwargs = {k: tuple(v) if isinstance(v, list) else v for k, v in json.loads(kwargs_json).items()}
    make_gym_env(simulator, **kwargs).close()  # lists as make_kwargs hands them: tuples


def plain_mapping(value: Any) -> Any:
    """OmegaConf containers (a Hydra-built config) as plain dicts and lists."""
    if OmegaConf.is_config(value):
        return OmegaConf.to_container(value, resolve=True)
    if isinstance(value, Mapping):
        return {str(k): plain_mapping(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [plain_mapping(v) for v in value]
    return value
