"""RL fine-tuning of a cloned controller in the simulator (PPO or TD3+BC).

    python recipes/finetune.py checkpoint=data/checkpoints/dannet_d_ii/best.pt
    python recipes/finetune.py algorithm=td3bc curriculum=summer_to_winter
    python recipes/finetune.py algorithm.regularizer=bc_demo time_budget_minutes=3

Writes to the run directory: ``best.pt`` / ``final.pt`` (actors for ``load_actor``),
``last.ckpt`` (resumable), ``success_curve.png``, ``evaluations.json``, ``results.json``
(before / after with Wilson intervals), ``metrics.json`` (the same, flat) and the TorchRL
CSV log. Running again in the same
directory resumes; a finished run (``done.json``) is skipped.
"""

from __future__ import annotations

import logging

import hydra
from omegaconf import DictConfig, OmegaConf

from pilerl.config import register_configs
from pilerl.rl import FinetuneConfig, finetune, register_rl_configs
from pilerl.rl.finetuning import flat_metrics
from pilerl.runtime import limit_threads
from pilerl.sweeps import is_done, mark_done

log = logging.getLogger(__name__)
register_configs()
register_rl_configs()


@hydra.main(config_path="../conf", config_name="finetune", version_base="1.3")
def main(cfg: DictConfig) -> float:
    """Returns the winter-or-first group's success rate after fine-tuning (best.pt)."""
    limit_threads()
    config: FinetuneConfig = OmegaConf.to_object(cfg)
    run_dir = config.output_dir
    if is_done(run_dir):
        log.info("%s already finished: skipping (delete done.json to run again)", run_dir)
        return float("nan")
    results = finetune(config, run_dir)
    mark_done(run_dir, flat_metrics(results))
    after = results["after_best"]
    return float(after.get("winter", next(iter(after.values())))["success_rate"])


if __name__ == "__main__":
    main()
