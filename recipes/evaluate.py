"""Closed-loop evaluation of a controller over seeded episodes in several conditions.

    python recipes/evaluate.py checkpoint=outputs/train_bc/<run>/best.pt
    python recipes/evaluate.py evaluation.episodes=20          # the scripted operator

Writes to the run directory: ``episodes.csv``, ``summary.json`` (success rate with 95%
Wilson interval per condition and pooled winter), ``success.png``, ``fill.png`` and
``videos/*.mp4``. A finished run directory is skipped when run again.
"""

from __future__ import annotations

import logging
from pathlib import Path

import hydra
from omegaconf import DictConfig, OmegaConf

from pilerl.config import EvaluateConfig, register_configs
from pilerl.evaluation.closed_loop import run_closed_loop
from pilerl.evaluation.evaluator import ActorController, ScriptedController, success_metrics
from pilerl.policies import load_actor
from pilerl.runtime import limit_threads
from pilerl.sweeps import is_done, mark_done

log = logging.getLogger(__name__)
register_configs()


@hydra.main(config_path="../conf", config_name="evaluate", version_base="1.3")
def main(cfg: DictConfig) -> float:
    """Returns the success rate over every evaluated episode (a sweep objective)."""
    limit_threads()
    config: EvaluateConfig = OmegaConf.to_object(cfg)
    out_dir = Path(config.output_dir)
    if is_done(out_dir):
        log.info("%s already finished: skipping (delete done.json to run again)", out_dir)
        return float("nan")

    # --- the controller: a checkpoint (loaded once here, so a bad file fails now) or scripted
    if config.checkpoint is None:
        controller = ScriptedController(config.operator, name=config.name or "scripted")
    else:
        load_actor(config.checkpoint)
        name = config.name or Path(config.checkpoint).resolve().parent.name
        controller = ActorController(config.checkpoint, name=name)

    # --- episodes, summary, plots, videos
    summary = run_closed_loop(
        controller,
        config.evaluation.plan(config.env),
        out_dir,
        workers=config.evaluation.workers,
        videos=config.evaluation.videos,
        video_conditions=config.evaluation.video_conditions,
        render_size=(config.evaluation.render_height, config.evaluation.render_width),
    )
    per_condition = [row for name, row in summary.items() if name in config.evaluation.conditions]
    success_rate = sum(r["successes"] for r in per_condition) / sum(
        r["episodes"] for r in per_condition
    )
    mark_done(
        out_dir,
        success_metrics(summary) | {"success_rate": success_rate},
    )
    return success_rate


if __name__ == "__main__":
    main()
