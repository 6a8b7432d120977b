"""The behaviour-cloning stage: a controller cloned from a dataset, with its loss plots.

``recipes/train_bc.py`` and the pipeline's cloning step both call these:
:func:`cloning_actor` builds the untrained controller (its initial weights drawn from the
seed), :func:`clone` trains it into a run directory (``best.pt``, ``final.pt``, ``last.pt``,
``losses.png``, the logger's files; an interrupted run resumes from ``last.pt``), and
:func:`clone_ensemble` trains many seeds at once for the curves of the paper's Fig. 4.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule

from pilerl.layout import RunLayout
from pilerl.loggers import make_logger
from pilerl.policies import controller_inputs, get_spec, make_actor, save_actor

from .bc import DEFAULT_DROPOUT_MASKS as BC_DEFAULT_MASKS
from .bc import BCSettings, epochs_for_steps, train_bc
from .ensemble import DEFAULT_DROPOUT_MASKS as ENSEMBLE_DEFAULT_MASKS
from .ensemble import train_bc_ensemble, write_ensemble_curves
from .plots import plot_ensemble, plot_losses

if TYPE_CHECKING:
    from pilerl.data import EpisodeStore

    from .settings import TrainBCConfig


class RecordedRun(Protocol):
    """What ``begin_bc_run`` needs of a recipe's run (``pilerl.recipe.Run``, a floor up)."""

    settings: dict[str, Any]

    def begin(self, **record: Any) -> None: ...


log = logging.getLogger(__name__)


def cloning_actor(
    policy: str,
    sensors: Sequence[str],
    attention_sensors: Sequence[str] | None,
    stats: dict,
    *,
    options: dict | None = None,
    seed: int,
) -> TensorDictModule:
    """The untrained controller ``policy`` reading the sensor set (s, s'), normalised by
    the dataset's ``stats``; its initial weights are drawn from ``seed`` (a fitted
    controller, the forest, takes ``seed`` as its own random state unless options set one)."""
    torch.manual_seed(seed)
    if get_spec(policy).trainer == "fit":  # torch's seed does not reach sklearn's forest
        options = {"seed": seed, **(options or {})}
    inputs, attention = controller_inputs(policy, sensors, attention_sensors)
    return make_actor(
        policy, sensors=inputs, stats=stats, attention_sensors=attention, options=options
    )


def bc_settings(
    policy: str,
    *,
    rows: int,
    epochs: int,
    gradient_steps: int | None,
    batch_size: int,
    learning_rate: float,
    seed: int,
    trainer: str | None,
    dropout_masks: str | None = None,
) -> BCSettings:
    """The training settings; ``gradient_steps`` (gradient training only) replaces
    ``epochs`` by as many epochs of ``rows`` as give about that many steps, while
    Levenberg-Marquardt rounds and a forest's fit keep ``epochs``."""
    if gradient_steps is not None and (trainer or get_spec(policy).trainer) == "gradient":
        epochs = epochs_for_steps(rows, batch_size, gradient_steps)
        log.info("gradient_steps=%d: %d epochs of %d rows", gradient_steps, epochs, rows)
    return BCSettings(
        epochs=epochs,
        batch_size=batch_size,
        learning_rate=learning_rate,
        seed=seed,
        trainer=trainer,
        dropout_masks=dropout_masks,
    )


def drawn_masks(dropout_masks: str | None, *, ensemble_seeds: int) -> str:
    """The dropout masks a run draws: ``dropout_masks``, else the trainer's default (one
    model: torch's ``bernoulli``; an ensemble: ``packed``). What a run directory records,
    so that ``null`` and the name it stands for are the same run."""
    if dropout_masks is not None:
        return dropout_masks
    return ENSEMBLE_DEFAULT_MASKS if ensemble_seeds > 1 else BC_DEFAULT_MASKS


def begin_bc_run(run: RecordedRun, config: TrainBCConfig, train_store: EpisodeStore) -> None:
    """Record a ``train_bc`` run in its directory, or stop there (``Run.begin``): a finished
    run is skipped, another config or dataset refused. The record holds the dropout masks
    drawn (``null`` as the name it stands for, and runs recorded before the key as the
    default they drew), the datasets' fingerprints, the control rate and the inputs."""
    rates = sorted({meta.rate_hz for meta in train_store.episodes})  # the control rate
    masks = drawn_masks(config.dropout_masks, ensemble_seeds=config.ensemble_seeds)
    run.begin(
        settings=run.settings | {"dropout_masks": masks},
        added={"dropout_masks": drawn_masks(None, ensemble_seeds=config.ensemble_seeds)},
        inputs={"train_data": config.train_data, "validation_data": config.validation_data},
        control_hz=rates[0] if len(rates) == 1 else rates,
        sensors=controller_inputs(config.policy.name, config.sensors.s, config.sensors.s_prime)[0],
    )


def clone(
    actor: TensorDictModule,
    train: TensorDict,
    validation: TensorDict | None,
    settings: BCSettings,
    run_dir: str | Path,
    *,
    logger_backend: str,
    title: str,
    draw_ahead: bool = False,
    draw_packed_ahead: bool = False,
) -> tuple[TensorDictModule, dict[str, float | int]]:
    """Train ``actor`` into ``run_dir``; returns (the trained actor, the run's metrics:
    epochs, final training loss and, with validation data, the final and best validation
    losses). Besides ``best.pt`` (lowest validation loss) and ``last.pt`` (training
    state), ``final.pt`` holds the actor after the whole budget. ``draw_ahead``,
    ``draw_packed_ahead``: as ``train_bc``'s."""
    layout = RunLayout(run_dir)
    logger = make_logger(logger_backend, layout.root, experiment_name="bc")
    actor, history = train_bc(
        actor,
        train,
        validation,
        settings,
        run_dir=layout.root,
        logger=logger,
        draw_ahead=draw_ahead,
        draw_packed_ahead=draw_packed_ahead,
    )
    save_actor(layout.final_actor, actor)
    plot_losses(history, layout.losses_plot, title=title)
    final = history[-1]
    metrics = {"epochs": final["epoch"], "train_loss": final["train_loss"]}
    if "validation_loss" in final:
        metrics["validation_loss"] = final["validation_loss"]
        metrics["best_validation_loss"] = min(row["validation_loss"] for row in history)
    return actor, metrics


def clone_ensemble(
    actor: TensorDictModule,
    seeds: Sequence[int],
    train: TensorDict,
    validation: TensorDict | None,
    settings: BCSettings,
    run_dir: str | Path,
    *,
    title: str,
    draw_ahead: bool = False,
    draw_packed_ahead: bool = False,
) -> dict[str, float | int]:
    """Train ``actor``'s architecture from each of ``seeds`` at once; writes
    ``ensemble.png`` and ``ensemble_curves.csv``; returns the final losses' mean and std.
    ``draw_ahead`` and ``draw_packed_ahead`` have no effect here (the ensemble draws every
    member's masks of a step in one call): as ``train_bc`` where nothing is drawn ahead,
    a warning says so."""
    if draw_ahead or draw_packed_ahead:
        option = "draw_ahead" if draw_ahead else "draw_packed_ahead"
        log.warning("clone_ensemble: %s has no effect: the ensemble draws its own masks", option)
    run_dir = Path(run_dir)
    result = train_bc_ensemble(actor.module.config, list(seeds), train, validation, settings)
    plot_ensemble(result.train_loss, result.validation_loss, run_dir / "ensemble.png", title=title)
    write_ensemble_curves(result, run_dir / "ensemble_curves.csv")
    final = result.train_loss if result.validation_loss is None else result.validation_loss
    return {
        "seeds": len(seeds),
        "final_loss_mean": float(final[:, -1].mean()),
        "final_loss_std": float(final[:, -1].std()),
    }


def bc_objective(metrics: dict) -> float:
    """The best validation loss, else the final training loss (or an ensemble's mean final
    loss): what the Optuna sweeper of ``recipes/train_bc.py`` minimises."""
    for key in ("best_validation_loss", "train_loss", "final_loss_mean"):
        if key in metrics:
            return float(metrics[key])
    raise KeyError("best_validation_loss")
