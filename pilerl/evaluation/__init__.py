"""Running controllers in a simulator and showing what happened.

| module | what |
|---|---|
| ``episode`` | ``run_episode``: one rollout of any controller as traces and frames |
| ``evaluator`` | ``evaluate``: N seeded episodes per condition as batched rollouts |
|  | (``pilerl.sim.rollout``) in worker processes, ``summarize`` |
| ``closed_loop`` | ``run_closed_loop``: evaluate, then results, plots and chosen videos |
| ``metrics`` | ``wilson_interval``, fill and cycle-time statistics, ``explainable_variance`` |
| ``failures`` | an episode's outcome in the simulator's words (its declared failure modes) |
| ``control_signals`` | the paper's Fig. 3: controllers' controls vs a demonstration |
| ``attention_masks`` | the paper's Fig. 5: attention masks per scoop phase |
| ``plots``, ``video``, ``scoop_report`` | signal plots, mp4, the scoop recipe's report |
"""

from .attention_masks import MaskTrace, PhaseMasks, phase_masks, plot_attention_masks
from .closed_loop import run_closed_loop
from .control_signals import (
    SCOOP_PHASES,
    ControlComparison,
    compare_controls,
    plot_control_signals,
    run_open_loop,
    scoop_phases,
)
from .episode import Episode, run_episode
from .evaluator import (
    ActorController,
    ActorWeights,
    EvaluationPlan,
    ScriptedController,
    evaluate,
    summarize,
    write_results,
)
from .metrics import wilson_interval
from .plots import plot_scoop
from .video import write_mp4

__all__ = [
    "SCOOP_PHASES",
    "ActorController",
    "ActorWeights",
    "ControlComparison",
    "Episode",
    "EvaluationPlan",
    "MaskTrace",
    "PhaseMasks",
    "ScriptedController",
    "compare_controls",
    "evaluate",
    "phase_masks",
    "plot_attention_masks",
    "plot_control_signals",
    "plot_scoop",
    "run_closed_loop",
    "run_episode",
    "run_open_loop",
    "scoop_phases",
    "summarize",
    "wilson_interval",
    "write_mp4",
    "write_results",
]
