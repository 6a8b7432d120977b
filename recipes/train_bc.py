"""Behaviour cloning of one of the paper's controllers on a demonstration dataset.

    python recipes/train_bc.py policy=dannet sensors=s_pt_sprime
    python recipes/train_bc.py policy=nnetv2 train_data=data/datasets/d_i_summer epochs=20

Writes to the run directory: ``best.pt`` (actor with the lowest validation loss),
``last.pt`` (resumable training state), ``losses.png``, the TorchRL CSV log and
``metrics.json``. Running again in the same directory resumes from ``last.pt``.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import hydra
import torch
from omegaconf import DictConfig, OmegaConf
from torchrl.record.loggers import get_logger

from pilerl.config import TrainBCConfig, register_configs
from pilerl.data import EpisodeStore
from pilerl.policies import make_actor
from pilerl.runtime import limit_threads
from pilerl.sweeps import METRICS_FILE, is_done, mark_done
from pilerl.training import BCSettings, train_bc
from pilerl.training.ensemble import train_bc_ensemble
from pilerl.training.plots import plot_ensemble, plot_losses

log = logging.getLogger(__name__)
register_configs()
LOGGERS = ("csv", "tensorboard", "none")


@hydra.main(config_path="../conf", config_name="train_bc", version_base="1.3")
def main(cfg: DictConfig) -> float:
    """Returns the best validation loss (else the final training loss): the objective of
    the Optuna sweeper (``hydra/sweeper=bc_optuna``)."""
    limit_threads()
    config: TrainBCConfig = OmegaConf.to_object(cfg)
    run_dir = Path(config.output_dir)
    if is_done(run_dir):
        log.info("%s already finished: skipping (delete done.json to run again)", run_dir)
        return _objective(json.loads((run_dir / METRICS_FILE).read_text()))
    if config.logger not in LOGGERS:
        raise ValueError(f"logger: unknown {config.logger!r}; known: {list(LOGGERS)}")

    # --- data: the training set carries the normalisation statistics
    train_store = EpisodeStore.open(config.train_data)
    if train_store.stats is None:
        raise ValueError(f"{config.train_data}: no statistics; build it with build_dataset.py")
    train = train_store.to_tensordict()
    validation = (
        EpisodeStore.open(config.validation_data).to_tensordict()
        if config.validation_data
        else None
    )

    # --- controller (initial weights from the seed) and settings
    torch.manual_seed(config.seed)
    actor = make_actor(
        config.policy.name,
        sensors=config.sensors.s,
        stats=train_store.stats,
        attention_sensors=config.sensors.s_prime,
        options=config.policy.options,
    )
    settings = BCSettings(
        epochs=config.epochs,
        batch_size=config.batch_size,
        learning_rate=config.learning_rate,
        seed=config.seed,
        trainer=config.trainer,
    )

    if config.ensemble_seeds > 1:  # many seeds at once: curves, not a deployable model
        seeds = list(range(config.seed, config.seed + config.ensemble_seeds))
        result = train_bc_ensemble(actor.module.config, seeds, train, validation, settings)
        plot_ensemble(
            result.train_loss,
            result.validation_loss,
            run_dir / "ensemble.png",
            title=f"{config.policy.name}, {len(seeds)} seeds",
        )
        final = result.train_loss if result.validation_loss is None else result.validation_loss
        mark_done(
            run_dir,
            {
                "seeds": len(seeds),
                "final_loss_mean": float(final[:, -1].mean()),
                "final_loss_std": float(final[:, -1].std()),
            },
        )
        return float(final[:, -1].mean())

    # --- one model: logger, training
    logger = (
        None
        if config.logger == "none"
        else get_logger(config.logger, logger_name=str(run_dir), experiment_name="bc")
    )
    actor, history = train_bc(actor, train, validation, settings, run_dir=run_dir, logger=logger)

    # --- what a person looks at
    plot_losses(
        history,
        run_dir / "losses.png",
        title=f"{config.policy.name}, s={len(config.sensors.s)} sensors",
    )
    final = history[-1]
    metrics = {"epochs": final["epoch"], "train_loss": final["train_loss"]}
    if "validation_loss" in final:
        metrics["validation_loss"] = final["validation_loss"]
        metrics["best_validation_loss"] = min(row["validation_loss"] for row in history)
    log.info("%s: %s", run_dir, metrics)
    mark_done(run_dir, metrics)
    return _objective(metrics)


def _objective(metrics: dict) -> float:
    return float(
        metrics.get(
            "best_validation_loss", metrics.get("train_loss", metrics.get("final_loss_mean"))
        )
    )


if __name__ == "__main__":
    main()
