"""The training room's settings: behaviour cloning in the train_bc recipe and the pipeline.

``TrainBCConfig`` is the primary schema of ``recipes/train_bc.py``; ``BCStepConfig`` is the
pipeline's ``bc`` node. Every field is checked in ``__post_init__``: a bad value fails when
the config is built, naming the field. The training numbers default to
``pilerl.training.BCSettings``'s (the paper's), which says what they do.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from omegaconf import MISSING

from pilerl import checks
from pilerl.evaluation.settings import ClosedLoopConfig
from pilerl.loggers import LoggerConfig
from pilerl.policies.settings import PolicyConfig, SensorsConfig, check_controller
from pilerl.sim.settings import EnvConfig

from .bc import BCSettings
from .dropout_masks import DROPOUT_MASKS

SELECTIONS = ("final", "best")  # the pipeline's cloned controller: bc/final.pt or bc/best.pt


@dataclass
class TrainBCConfig:
    """The train_bc recipe: behaviour cloning of one controller on one dataset.

    Attributes:
        train_data: training dataset directory (``recipes/build_dataset.py``).
        validation_data: held-out demonstrations for the validation loss, or ``None``.
        epochs, batch_size, learning_rate, seed: ``pilerl.training.BCSettings`` (the
            paper's defaults: RAdam, batch 512, lr 1e-3, 150 epochs, MSE).
        gradient_steps: if set, replaces ``epochs`` for gradient training by as many epochs
            as give about this many steps (at least one), so datasets of different sizes
            get the same training budget (D_I has 27x the rows of D_II). Levenberg-Marquardt
            rounds and the forest's fit do not depend on the dataset size; they keep
            ``epochs``.
        logger: the TorchRL metric logger (``logger`` group: csv, tensorboard, none).
        trainer: ``gradient``, ``levenberg_marquardt`` or ``fit``; ``None`` = the
            controller's default (NNet: Levenberg-Marquardt).
        ensemble_seeds: > 1 trains that many seeds at once (``torch.func``) and plots
            mean +- std curves (the paper's Fig. 4) instead of one model.
        dropout_masks: how dropout draws its masks in training (``BCSettings``):
            ``bernoulli`` (torch's own draws), ``packed`` (cheaper draws of the same
            distribution: other weights for the same seed); ``None`` = the trainer's
            default: ``bernoulli`` for one model (the weights it always gave), ``packed``
            for an ensemble.
        draw_ahead: draw torch's masks a step ahead on a second thread
            (``pilerl.training.draw_ahead``): the same results, faster only where a second
            core is idle. Not with ``dropout_masks: packed``; where nothing is drawn ahead
            (Levenberg-Marquardt, no dropout, the forest, an ensemble) a warning says so.
        draw_packed_ahead: the same for packed masks (``dropout_masks: packed`` for one
            model): the results of packed masks drawn in the step, the draws on a second
            thread.
        env, evaluation: the closed-loop test of the trained controller (the last step;
            ``evaluation.episodes: 0`` skips it), written to ``<run dir>/evaluation``.
    """

    policy: PolicyConfig = field(default_factory=PolicyConfig)
    sensors: SensorsConfig = field(default_factory=SensorsConfig)
    train_data: str = MISSING
    validation_data: str | None = None
    epochs: int = BCSettings.epochs
    gradient_steps: int | None = None
    batch_size: int = BCSettings.batch_size
    learning_rate: float = BCSettings.learning_rate
    seed: int = BCSettings.seed
    logger: LoggerConfig = field(default_factory=LoggerConfig)
    trainer: str | None = None
    ensemble_seeds: int = 1
    dropout_masks: str | None = None
    draw_ahead: bool = False
    draw_packed_ahead: bool = False
    env: EnvConfig = field(default_factory=EnvConfig)
    evaluation: ClosedLoopConfig = field(default_factory=lambda: ClosedLoopConfig(episodes=0))
    output_dir: str = MISSING

    def __post_init__(self) -> None:
        from pilerl.policies.registry import TRAINERS

        if self.train_data != MISSING:
            checks.path("train_data", self.train_data)
        if self.validation_data is not None:
            checks.path("validation_data", self.validation_data)
        checks.positive_int("epochs", self.epochs)
        if self.gradient_steps is not None:
            checks.positive_int("gradient_steps", self.gradient_steps)
        checks.positive_int("batch_size", self.batch_size)
        checks.positive("learning_rate", self.learning_rate)
        checks.non_negative_int("seed", self.seed)
        if self.trainer is not None:
            checks.one_of("trainer", self.trainer, TRAINERS)
        checks.positive_int("ensemble_seeds", self.ensemble_seeds)
        if self.dropout_masks is not None and self.dropout_masks not in DROPOUT_MASKS:
            raise ValueError(
                f"dropout_masks: unknown {self.dropout_masks!r}; known: {list(DROPOUT_MASKS)} "
                "(null = the trainer's default)"
            )
        # an ensemble draws its own masks (draw_ahead only warns there): one model only
        if self.draw_ahead and self.dropout_masks == "packed" and self.ensemble_seeds == 1:
            raise ValueError(
                "draw_ahead: draws torch's bernoulli masks ahead, dropout_masks=packed asks "
                "for packed ones; set draw_ahead=false or dropout_masks=bernoulli (packed "
                "masks are drawn ahead with draw_packed_ahead=true)"
            )
        if self.draw_packed_ahead and self.dropout_masks != "packed" and self.ensemble_seeds == 1:
            raise ValueError(
                f"draw_packed_ahead: draws packed masks ahead, dropout_masks="
                f"{self.dropout_masks or 'null'} draws torch's; set dropout_masks=packed "
                "(other weights than torch's draws) or draw_ahead=true instead (torch's "
                "masks ahead)"
            )
        self.evaluation.condition_names(self.env)
        if self.ensemble_seeds > 1 and self.evaluation.episodes > 0:
            raise ValueError(
                "evaluation.episodes: an ensemble (ensemble_seeds > 1) has no one "
                "controller to test in closed loop; set evaluation.episodes=0"
            )
        check_controller(self.policy, self.sensors, trainer=self.trainer)


@dataclass
class BCStepConfig:
    """Behaviour cloning in the pipeline (``pilerl.training.BCSettings``).

    Attributes:
        gradient_steps: training budget in gradient steps (epochs follow from the size).
        batch_size, learning_rate, seed: as in ``recipes/train_bc.py``.
        selection: which weights the pipeline evaluates and fine-tunes: ``final`` (the
            weights after the whole budget, ``bc/final.pt``: the paper trains a fixed 150
            epochs and uses its winter demonstrations only to plot the validation loss) or
            ``best`` (``bc/best.pt``, the epoch with the lowest winter validation loss:
            a choice made on the test condition, which with the reactive operator picks
            an early, under-trained epoch; docs/training.md, "Which weights").
    """

    gradient_steps: int = 3000
    batch_size: int = BCSettings.batch_size
    learning_rate: float = BCSettings.learning_rate
    seed: int = BCSettings.seed
    selection: str = "final"

    def __post_init__(self) -> None:
        checks.positive_int("bc.gradient_steps", self.gradient_steps)
        checks.positive_int("bc.batch_size", self.batch_size)
        checks.positive("bc.learning_rate", self.learning_rate)
        checks.non_negative_int("bc.seed", self.seed)
        checks.one_of("bc.selection", self.selection, SELECTIONS)
