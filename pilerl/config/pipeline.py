"""The pipeline recipe's typed config: demonstrations → BC → evaluation → RL → report.

Kept apart from ``schema.py`` because it includes the RL schemas (``pilerl.rl.config``),
which themselves build on ``schema.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from omegaconf import MISSING

from pilerl.rl.config import FinetuneConfig

from . import checks
from .schema import (
    ClosedLoopConfig,
    EnvConfig,
    LoggerConfig,
    PolicyConfig,
    SensorsConfig,
    check_controller,
)


@dataclass
class PipelineDemosConfig:
    """Scripted demonstrations recorded by the pipeline.

    Attributes:
        episodes: summer demonstrations (the paper: 72); the successful ones become D_II.
        validation_episodes: winter_c demonstrations by operators who feel the contact
            (telescope-pressure cue): the validation loss and the Fig. 3 / Fig. 5 data.
        record_hz: recording (= control) rate [Hz]; 20 Hz is D_II's rate.
        mistake_rate: share of operators who raise the boom too early.
        seed: base seed of the recordings.
        workers: recording processes.
    """

    episodes: int = 30
    validation_episodes: int = 4
    record_hz: float = 20.0
    mistake_rate: float = 0.28
    seed: int = 0
    workers: int = 2

    def __post_init__(self) -> None:
        checks.positive_int("demos.episodes", self.episodes)
        checks.positive_int("demos.validation_episodes", self.validation_episodes)
        checks.positive("demos.record_hz", self.record_hz)
        checks.fraction("demos.mistake_rate", self.mistake_rate)
        checks.non_negative_int("demos.seed", self.seed)
        checks.positive_int("demos.workers", self.workers)

    def check_rate(self, env: EnvConfig) -> None:
        """``record_hz`` is a control rate ``env``'s simulator accepts (the pile loader: at
        most its physics rate)."""
        try:
            env.make_kwargs(control_hz=self.record_hz)
        except ValueError as error:
            raise ValueError(f"demos.record_hz ({self.record_hz}): {error}") from None


@dataclass
class PipelineBCConfig:
    """Behaviour cloning in the pipeline (``pilerl.training.BCSettings``).

    Attributes:
        gradient_steps: training budget in gradient steps (epochs follow from the size).
        batch_size, learning_rate, seed: as in ``recipes/train_bc.py``.
    """

    gradient_steps: int = 3000
    batch_size: int = 512
    learning_rate: float = 1e-3
    seed: int = 0

    def __post_init__(self) -> None:
        checks.positive_int("bc.gradient_steps", self.gradient_steps)
        checks.positive_int("bc.batch_size", self.batch_size)
        checks.positive("bc.learning_rate", self.learning_rate)
        checks.non_negative_int("bc.seed", self.seed)


@dataclass
class PipelineConfig:
    """The main job. ``finetune.checkpoint`` / ``finetune.demos`` / ``finetune.output_dir``
    name where the BC and dataset steps write (interpolated from ``output_dir`` in
    ``conf/pipeline.yaml``), so every stage reads what the previous one wrote."""

    env: EnvConfig = field(default_factory=EnvConfig)
    demos: PipelineDemosConfig = field(default_factory=PipelineDemosConfig)
    policy: PolicyConfig = field(default_factory=PolicyConfig)
    sensors: SensorsConfig = field(default_factory=SensorsConfig)
    bc: PipelineBCConfig = field(default_factory=PipelineBCConfig)
    evaluation: ClosedLoopConfig = field(default_factory=ClosedLoopConfig)
    finetune: FinetuneConfig = field(default_factory=FinetuneConfig)
    logger: LoggerConfig = field(default_factory=LoggerConfig)
    output_dir: str = MISSING

    def __post_init__(self) -> None:
        from pilerl.policies import NEURAL_CONTROLLERS

        if self.policy.name != MISSING and self.policy.name not in NEURAL_CONTROLLERS:
            raise ValueError(
                f"policy: {self.policy.name!r} cannot be fine-tuned by RL (not "
                f"differentiable); choose one of {list(NEURAL_CONTROLLERS)}"
            )
        self.demos.check_rate(self.env)
        self.evaluation.condition_names(self.env)
        check_controller(self.policy, self.sensors, trainer=None)
