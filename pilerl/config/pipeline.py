"""The pipeline recipe's typed config: demonstrations → BC → evaluation → RL → report.

Composed from the rooms' settings (recording in ``pilerl.data``, the controller in
``pilerl.policies``, BC in ``pilerl.training``, closed-loop tests in ``pilerl.evaluation``,
fine-tuning in ``pilerl.rl``); it only adds the checks that span several of them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from omegaconf import MISSING

from pilerl.data.settings import DemosConfig
from pilerl.evaluation.settings import ClosedLoopConfig
from pilerl.loggers import LoggerConfig
from pilerl.policies.settings import PolicyConfig, SensorsConfig, check_controller
from pilerl.rl.config import FinetuneConfig
from pilerl.sim.settings import EnvConfig
from pilerl.training.settings import BCStepConfig


@dataclass
class PipelineConfig:
    """The main job. ``finetune.checkpoint`` / ``finetune.demos`` / ``finetune.output_dir``
    name where the BC and dataset steps write (interpolated from ``output_dir`` in
    ``conf/pipeline.yaml``), so every stage reads what the previous one wrote."""

    env: EnvConfig = field(default_factory=EnvConfig)
    demos: DemosConfig = field(default_factory=DemosConfig)
    policy: PolicyConfig = field(default_factory=PolicyConfig)
    sensors: SensorsConfig = field(default_factory=SensorsConfig)
    bc: BCStepConfig = field(default_factory=BCStepConfig)
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
        self.demos.check_expert(self.env)
        self.evaluation.condition_names(self.env)
        check_controller(self.policy, self.sensors, trainer=None)
