"""RL fine-tuning of cloned controllers in the simulator (PPO, TD3+BC, RLPD, residual RL).

| module | what |
|---|---|
| ``config`` | ``FinetuneConfig``, the learners' settings (``ALGORITHMS``), checked when built |
| ``envs`` | ``ConditionMixtureEnv``: conditions drawn per episode, reward from named parts |
| ``critics`` | value and Q networks over normalised sensors |
| ``regularizers`` | BC on demo batches, MSE to the frozen cloned actor |
| ``ppo`` | ``PPOLearner``: ``ClipPPOLoss`` + ``GAE`` |
| ``td3bc`` | ``TD3BCLearner``: ``TD3BCLoss``, twin Q, demos in replay |
| ``rlpd`` | ``RLPDLearner``: symmetric demo/online sampling, LayerNorm Q ensemble, high UTD |
| ``residual`` | a residual actor on the frozen clone, its checkpoint and evaluation |
| ``scoops`` | ``count_scoops``: episodes, failed and tipped ones, in a collected batch |
| ``collection`` | TorchRL collectors: single process, multi-process, Ray |
| ``evaluation`` | pooled success per condition group, videos, success curve |
| ``finetuning`` | ``finetune(config, run_dir)``: the loop, checkpoints, resume |

See docs/finetuning.md.
"""

from .config import (
    ALGORITHMS,
    CollectionConfig,
    CurriculumConfig,
    CurriculumStage,
    EvaluationConfig,
    FinetuneConfig,
    LearnerConfig,
    PPOConfig,
    RLPDConfig,
    TD3BCConfig,
)
from .finetuning import finetune, load_cloned_actor

__all__ = [
    "ALGORITHMS",
    "CollectionConfig",
    "CurriculumConfig",
    "CurriculumStage",
    "EvaluationConfig",
    "FinetuneConfig",
    "LearnerConfig",
    "PPOConfig",
    "RLPDConfig",
    "TD3BCConfig",
    "finetune",
    "load_cloned_actor",
]
