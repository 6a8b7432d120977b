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

import logging

import hydra
from omegaconf import DictConfig, OmegaConf

from pilerl.config import register_configs
from pilerl.policies.checkpoint import warn_if_other_control_rate
from pilerl.rendering import resolve_videos
from pilerl.rl import FinetuneConfig, finetune
from pilerl.rl.config import uses_demos
from pilerl.rl.finetuning import flat_metrics
from pilerl.runs import begin_run, finish_run, resolve_checkpoint
from pilerl.runtime import limit_threads

log = logging.getLogger(__name__)
register_configs()
# budgets that may be raised to continue a finished run from its last.ckpt
GROWABLE = ("curriculum.stages.*.frames", "time_budget_minutes")


@hydra.main(config_path="../conf", config_name="finetune", version_base="1.3")
def main(cfg: DictConfig) -> float:
    """Returns the winter-or-first group's success rate after fine-tuning (best.pt)."""
    limit_threads()
    config: FinetuneConfig = OmegaConf.to_object(cfg)
    config.checkpoint = str(resolve_checkpoint(config.checkpoint))
    warn_if_other_control_rate(config.checkpoint, config.env.control_hz)
    config.evaluation.video = resolve_videos(config.evaluation.video, where="evaluation.video")
    run_dir = config.output_dir
    config.check_inputs()  # the inputs exist: all before any work
    inputs = {
        "checkpoint": config.checkpoint,
        "demos": config.demos if uses_demos(config) else None,
    }
    settings = OmegaConf.to_container(cfg, resolve=True)
    facts = {"control_hz": config.env.control_hz}
    if begin_run(run_dir, settings, inputs=inputs, growable=GROWABLE, **facts):
        log.info("%s already finished: skipping (same settings)", run_dir)
        return float("nan")
    results = finetune(config, run_dir)
    finish_run(run_dir, flat_metrics(results))
    after = results["after_best"]
    return float(after.get("winter", next(iter(after.values())))["success_rate"])


if __name__ == "__main__":
    main()
