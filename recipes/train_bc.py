"""Behaviour cloning of one of the paper's controllers on a demonstration dataset.

    python recipes/train_bc.py policy=dannet sensors=s_pt_sprime
    python recipes/train_bc.py policy=nnetv2 train_data=data/datasets/d_i_summer epochs=20
    python recipes/train_bc.py policy=rf evaluation.episodes=10   # + closed-loop test
    python recipes/train_bc.py dropout_masks=packed    # cheaper dropout draws, other weights
    python recipes/train_bc.py draw_ahead=true         # torch's draws on a 2nd core, same weights
    python recipes/train_bc.py dropout_masks=packed draw_packed_ahead=true   # both

Writes to the run directory: ``best.pt`` (actor with the lowest validation loss),
``last.pt`` (resumable training state), ``losses.png``, the TorchRL CSV log and
``metrics.json``; with ``evaluation.episodes > 0`` the closed-loop test of ``best.pt``
goes to ``evaluation/`` (see ``recipes/evaluate.py``). Running again in the same
directory resumes from ``last.pt`` (or skips a finished run); ``run.json`` records the
settings and the datasets' fingerprints, and another policy, sensor set, budget or dataset
is refused with the differing keys named.
"""

from __future__ import annotations

import logging

from pilerl.config import register_configs
from pilerl.data import EpisodeStore
from pilerl.evaluation.evaluator import ActorController, success_metrics
from pilerl.evaluation.stage import closed_loop_plan, evaluate_controller
from pilerl.recipe import Run, recipe
from pilerl.rendering import resolve_videos
from pilerl.training.clone import (
    bc_objective,
    bc_settings,
    begin_bc_run,
    clone,
    clone_ensemble,
    cloning_actor,
)
from pilerl.training.settings import TrainBCConfig

log = logging.getLogger(__name__)
register_configs()


@recipe("train_bc", objective=bc_objective)
def main(config: TrainBCConfig, run: Run) -> dict[str, float]:
    """Returns the best validation loss (else the final training loss): the objective of
    the Optuna sweeper (``hydra/sweeper=bc_optuna``)."""
    videos = resolve_videos(
        config.evaluation.videos, where="evaluation.videos", renders=config.env.plugin().renders
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

    # --- controller (initial weights from the seed), settings, the closed-loop plan
    policy, sensors = config.policy, config.sensors
    actor = cloning_actor(
        policy.name,
        sensors.s,
        sensors.s_prime,
        train_store.stats,
        options=policy.options,
        seed=config.seed,
    )
    if config.evaluation.episodes > 0:  # a bad condition or env setting fails now
        plan = closed_loop_plan(config.evaluation, config.env)
    settings = bc_settings(
        policy.name,
        rows=train.batch_size[0],
        epochs=config.epochs,
        gradient_steps=config.gradient_steps,
        batch_size=config.batch_size,
        learning_rate=config.learning_rate,
        seed=config.seed,
        trainer=config.trainer,
        dropout_masks=config.dropout_masks,
    )

    # --- this run directory: skip when finished, refuse another config or dataset
    begin_bc_run(run, config, train_store)
    ahead = {"draw_ahead": config.draw_ahead, "draw_packed_ahead": config.draw_packed_ahead}
    if config.ensemble_seeds > 1:  # many seeds at once: curves, not a deployable model
        seeds = range(config.seed, config.seed + config.ensemble_seeds)
        title = f"{policy.name}, {len(seeds)} seeds"
        return clone_ensemble(
            actor, seeds, train, validation, settings, run.dir, title=title, **ahead
        )

    # --- one model, then the trained controller in closed loop
    title = f"{policy.name}, s={len(sensors.s)} sensors"
    _, metrics = clone(
        actor,
        train,
        validation,
        settings,
        run.dir,
        logger_backend=config.logger.backend,
        title=title,
        **ahead,  # the dropout masks drawn on a second thread (the same weights)
    )
    log.info("%s: %s", run.dir, metrics)
    if config.evaluation.episodes > 0:
        controller = ActorController(str(run.layout.best_actor), name=policy.name)
        summary = evaluate_controller(
            controller, plan, config.evaluation, run.layout.sub("evaluation").root, videos=videos
        )
        metrics |= success_metrics(summary)
    return metrics


if __name__ == "__main__":
    main()
