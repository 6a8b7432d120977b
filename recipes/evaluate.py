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

import logging
from pathlib import Path

import hydra
from omegaconf import DictConfig, OmegaConf

from pilerl.config import register_configs
from pilerl.evaluation.closed_loop import run_closed_loop
from pilerl.evaluation.evaluator import (
    ActorController,
    ScriptedController,
    build_envs,
    success_metrics,
)
from pilerl.evaluation.settings import EvaluateConfig
from pilerl.policies import load_actor
from pilerl.rendering import resolve_videos
from pilerl.runs import begin_run, finish_run, resolve_checkpoint
from pilerl.runtime import limit_threads

log = logging.getLogger(__name__)
register_configs()


@hydra.main(config_path="../conf", config_name="evaluate", version_base="1.3")
def main(cfg: DictConfig) -> float:
    """Returns the success rate over every evaluated episode (a sweep objective)."""
    limit_threads()
    config: EvaluateConfig = OmegaConf.to_object(cfg)
    out_dir = Path(config.output_dir)
    checkpoint = resolve_checkpoint(config.checkpoint) if config.checkpoint else None
    videos = resolve_videos(config.evaluation.videos, where="evaluation.videos")
    # --- the controller: a checkpoint (loaded once here, so a bad file fails now) or scripted
    if checkpoint is None:
        controller = ScriptedController(
            config.expert, name=config.name or "scripted", simulator=config.env.simulator
        )
    else:
        load_actor(checkpoint)
        name = config.name or checkpoint.resolve().parent.name
        controller = ActorController(str(checkpoint), name=name)
    plan = config.evaluation.plan(config.env)
    build_envs(plan)  # a bad condition or env setting fails now, before anything is written
    settings = OmegaConf.to_container(cfg, resolve=True)
    if begin_run(out_dir, settings, inputs={"checkpoint": checkpoint}):
        log.info("%s already finished: skipping (same settings)", out_dir)
        return float("nan")

    # --- episodes, summary, plots, videos
    summary = run_closed_loop(
        controller,
        plan,
        out_dir,
        workers=config.evaluation.workers,
        videos=videos,
        video_conditions=config.evaluation.video_conditions,
        render_size=(config.evaluation.render_height, config.evaluation.render_width),
    )
    per_condition = [row for name, row in summary.items() if name in plan.conditions]
    success_rate = sum(r["successes"] for r in per_condition) / sum(
        r["episodes"] for r in per_condition
    )
    finish_run(out_dir, success_metrics(summary) | {"success_rate": success_rate})
    return success_rate


if __name__ == "__main__":
    main()
