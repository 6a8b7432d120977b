"""Behaviour cloning of one of the paper's controllers on a demonstration dataset.

    python recipes/train_bc.py policy=dannet sensors=s_pt_sprime
    python recipes/train_bc.py policy=nnetv2 train_data=data/datasets/d_i_summer epochs=20
    python recipes/train_bc.py policy=rf evaluation.episodes=10   # + closed-loop test

Writes to the run directory: ``best.pt`` (actor with the lowest validation loss),
``last.pt`` (resumable training state), ``losses.png``, the TorchRL CSV log and
``metrics.json``; with ``evaluation.episodes > 0`` the closed-loop test of ``best.pt``
goes to ``evaluation/`` (see ``recipes/evaluate.py``). Running again in the same
directory resumes from ``last.pt`` (or skips a finished run); ``run.json`` records the
settings and the datasets' fingerprints, and another policy, sensor set, budget or dataset
is refused with the differing keys named.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import hydra
import torch
from omegaconf import DictConfig, OmegaConf

from pilerl.config import register_configs
from pilerl.data import EpisodeStore
from pilerl.evaluation.closed_loop import run_closed_loop
from pilerl.evaluation.evaluator import ActorController, build_envs, success_metrics
from pilerl.loggers import make_logger
from pilerl.policies import controller_inputs, get_spec, make_actor
from pilerl.rendering import resolve_videos
from pilerl.runs import begin_run, finish_run
from pilerl.runtime import limit_threads
from pilerl.sweeps import METRICS_FILE
from pilerl.training import (
    BCSettings,
    epochs_for_steps,
    train_bc,
    train_bc_ensemble,
    write_ensemble_curves,
)
from pilerl.training.plots import plot_ensemble, plot_losses
from pilerl.training.settings import TrainBCConfig

log = logging.getLogger(__name__)
register_configs()


@hydra.main(config_path="../conf", config_name="train_bc", version_base="1.3")
def main(cfg: DictConfig) -> float:
    """Returns the best validation loss (else the final training loss): the objective of
    the Optuna sweeper (``hydra/sweeper=bc_optuna``)."""
    limit_threads()
    config: TrainBCConfig = OmegaConf.to_object(cfg)
    run_dir = Path(config.output_dir)
    videos = resolve_videos(config.evaluation.videos, where="evaluation.videos")
    if config.ensemble_seeds > 1 and config.evaluation.episodes > 0:
        raise ValueError(
            "evaluation.episodes: an ensemble (ensemble_seeds > 1) has no one "
            "controller to test in closed loop; set evaluation.episodes=0"
        )

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
    sensors, attention_sensors = controller_inputs(
        config.policy.name, config.sensors.s, config.sensors.s_prime
    )
    actor = make_actor(
        config.policy.name,
        sensors=sensors,
        stats=train_store.stats,
        attention_sensors=attention_sensors,
        options=config.policy.options,
    )
    if config.evaluation.episodes > 0:
        plan = config.evaluation.plan(config.env)
        build_envs(plan)  # a bad condition or env setting fails now, not after training
    settings = BCSettings(
        epochs=_epochs(config, train.batch_size[0]),
        batch_size=config.batch_size,
        learning_rate=config.learning_rate,
        seed=config.seed,
        trainer=config.trainer,
    )

    # --- this run directory: skip when finished, refuse another config or dataset
    inputs = {"train_data": config.train_data, "validation_data": config.validation_data}
    rates = sorted({meta.rate_hz for meta in train_store.episodes})  # the control rate
    control_hz = rates[0] if len(rates) == 1 else rates
    resolved = OmegaConf.to_container(cfg, resolve=True)
    if begin_run(run_dir, resolved, inputs=inputs, control_hz=control_hz, sensors=sensors):
        log.info("%s already finished: skipping (same settings and data)", run_dir)
        return _objective(json.loads((run_dir / METRICS_FILE).read_text()))

    if config.ensemble_seeds > 1:  # many seeds at once: curves, not a deployable model
        seeds = list(range(config.seed, config.seed + config.ensemble_seeds))
        result = train_bc_ensemble(actor.module.config, seeds, train, validation, settings)
        plot_ensemble(
            result.train_loss,
            result.validation_loss,
            run_dir / "ensemble.png",
            title=f"{config.policy.name}, {len(seeds)} seeds",
        )
        write_ensemble_curves(result, run_dir / "ensemble_curves.csv")
        final = result.train_loss if result.validation_loss is None else result.validation_loss
        finish_run(
            run_dir,
            {
                "seeds": len(seeds),
                "final_loss_mean": float(final[:, -1].mean()),
                "final_loss_std": float(final[:, -1].std()),
            },
        )
        return float(final[:, -1].mean())

    # --- one model: logger, training
    logger = make_logger(config.logger.backend, run_dir, experiment_name="bc")
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

    # --- last step: the trained controller in closed loop
    if config.evaluation.episodes > 0:
        summary = run_closed_loop(
            ActorController(str(run_dir / "best.pt"), name=config.policy.name),
            plan,
            run_dir / "evaluation",
            workers=config.evaluation.workers,
            videos=videos,
            video_conditions=config.evaluation.video_conditions,
            render_size=(config.evaluation.render_height, config.evaluation.render_width),
        )
        metrics |= success_metrics(summary)
    finish_run(run_dir, metrics)
    return _objective(metrics)


def _epochs(config: TrainBCConfig, rows: int) -> int:
    """``epochs``, or as many as give about ``gradient_steps`` steps (gradient training)."""
    trainer = config.trainer or get_spec(config.policy.name).trainer
    if config.gradient_steps is None or trainer != "gradient":
        return config.epochs
    epochs = epochs_for_steps(rows, config.batch_size, config.gradient_steps)
    log.info("gradient_steps=%d: %d epochs of %d rows", config.gradient_steps, epochs, rows)
    return epochs


def _objective(metrics: dict) -> float:
    return float(
        metrics.get(
            "best_validation_loss", metrics.get("train_loss", metrics.get("final_loss_mean"))
        )
    )


if __name__ == "__main__":
    main()
