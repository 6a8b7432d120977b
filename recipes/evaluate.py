"""Closed-loop evaluation of a controller over seeded episodes in several conditions.

    python recipes/evaluate.py checkpoint=outputs/train_bc/<run>/best.pt
    python recipes/evaluate.py evaluation.episodes=20          # the scripted operator

Writes to the run directory: ``episodes.csv``, ``summary.json`` (success rate with 95%
Wilson interval per condition and pooled winter), ``success.png``, ``fill.png`` and
``videos/*.mp4`` (after the results; ``evaluation.videos=auto`` renders when this machine
can). ``checkpoint=`` takes a checkpoint file or a run directory holding ``best.pt``. A
finished run directory is skipped when run again with the same settings and checkpoint,
and refused when they differ (``run.json``).
"""

from __future__ import annotations

from pilerl.config import register_configs
from pilerl.evaluation.evaluator import ActorController, ScriptedController, success_metrics
from pilerl.evaluation.settings import EvaluateConfig
from pilerl.evaluation.stage import closed_loop_plan, evaluate_controller, success_rate
from pilerl.policies import load_actor
from pilerl.recipe import Run, recipe
from pilerl.rendering import resolve_videos
from pilerl.runs import resolve_checkpoint

register_configs()


@recipe("evaluate", objective="success_rate")
def main(config: EvaluateConfig, run: Run) -> dict[str, float]:
    """Returns the success rate over every evaluated episode (a sweep objective)."""
    checkpoint = resolve_checkpoint(config.checkpoint) if config.checkpoint else None
    videos = resolve_videos(
        config.evaluation.videos, where="evaluation.videos", renders=config.env.plugin().renders
    )
    # --- the controller: a checkpoint (loaded once here, so a bad file fails now) or scripted
    if checkpoint is None:
        controller = ScriptedController(
            config.expert, name=config.name or "scripted", simulator=config.env.simulator
        )
    else:
        load_actor(checkpoint)
        name = config.name or checkpoint.resolve().parent.name
        controller = ActorController(str(checkpoint), name=name)
    plan = closed_loop_plan(config.evaluation, config.env)  # a bad condition fails now
    expert_revision = None if checkpoint else config.env.plugin().expert_revision
    run.begin(inputs={"checkpoint": checkpoint}, scripted_expert_revision=expert_revision)

    # --- episodes, summary, plots, videos
    summary = evaluate_controller(
        controller, plan, config.evaluation, config.output_dir, videos=videos
    )
    rate = success_rate(summary, plan.conditions)
    return success_metrics(summary) | {"success_rate": rate}


if __name__ == "__main__":
    main()
