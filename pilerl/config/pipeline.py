"""The pipeline recipe's typed config: demonstrations → BC → evaluation → RL → report.

Kept apart from ``schema.py`` because it includes the RL schemas (``pilerl.rl.config``),
which themselves build on ``schema.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from omegaconf import MISSING

from pilerl.rl.config import FinetuneConfig

from .schema import ClosedLoopConfig, EnvConfig, LoggerConfig, PolicyConfig, SensorsConfig


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
