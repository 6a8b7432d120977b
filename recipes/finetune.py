"""RL fine-tuning of a cloned controller in the simulator (PPO or TD3+BC).

    python recipes/finetune.py checkpoint=outputs/bc/dannet            # a train_bc run dir
    python recipes/finetune.py checkpoint=outputs/bc/dannet/best.pt algorithm=td3bc \
        demos=data/datasets/d_ii_summer curriculum=summer_to_winter

Writes to the run directory: ``best.pt`` / ``final.pt`` (actors for ``load_actor``),
``last.ckpt`` (resumable), ``success_curve.png``, ``evaluations.json``, ``results.json``
(before / after with Wilson intervals), ``metrics.json`` (the same, flat) and the TorchRL
CSV log. Running again in the same
directory resumes (also with larger stage frames or ``time_budget_minutes``); a
finished run is skipped; other settings or another checkpoint are refused (``run.json``).
"""

from __future__ import annotations

from pilerl.config import register_configs
from pilerl.policies.checkpoint import warn_if_other_control_rate
from pilerl.recipe import Run, recipe
from pilerl.rendering import resolve_videos
from pilerl.rl import FinetuneConfig, finetune
from pilerl.rl.config import uses_demos
from pilerl.rl.finetuning import flat_metrics
from pilerl.runs import resolve_checkpoint

register_configs()
# budgets that may be raised to continue a finished run from its last.ckpt
GROWABLE = ("curriculum.stages.*.frames", "time_budget_minutes")
# settings added after runs were recorded without them: the value those runs ran with
ADDED = {"collection.env_variants": []}


def first_group_success(metrics: dict) -> float:
    """The first evaluation group's success rate after fine-tuning (``best.pt``): by
    default the simulator's first declared group (the pile loader's winter A-D)."""
    rates = [
        v for k, v in metrics.items() if k.startswith("after_best_") and k.endswith("_success_rate")
    ]
    if not rates:
        raise ValueError(f"finetune objective: no after_best_*_success_rate in {sorted(metrics)}")
    return float(rates[0])


@recipe("finetune", objective=first_group_success)
def main(config: FinetuneConfig, run: Run) -> dict[str, float]:
    """Returns the first evaluation group's success rate after fine-tuning (best.pt)."""
    config.checkpoint = str(resolve_checkpoint(config.checkpoint))
    warn_if_other_control_rate(config.checkpoint, config.env.control_hz)
    config.evaluation.video = resolve_videos(
        config.evaluation.video, where="evaluation.video", renders=config.env.plugin().renders
    )
    config.check_inputs()  # the inputs exist: all before any work
    inputs = {
        "checkpoint": config.checkpoint,
        "demos": config.demos if uses_demos(config) else None,
    }
    run.begin(inputs=inputs, growable=GROWABLE, added=ADDED, control_hz=config.env.control_hz)
    return flat_metrics(finetune(config, run.dir))


if __name__ == "__main__":
    main()
