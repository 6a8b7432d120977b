"""Behaviour cloning: fit a controller to demonstrations, as the paper does.

Paper defaults (``BCSettings``): MSE loss (as TorchRL's ``BCLoss``), RAdam, batch 512, learning
rate 1e-3, 150 epochs, seeded. The validation loss (MSE on held-out demonstrations, e.g.
winter ones) is computed after every epoch. Each controller has a default trainer
(``pilerl.policies`` registry): NNet is trained with Levenberg-Marquardt as Halbach et al.
did (an epoch = ``lm_iterations`` damped Gauss-Newton steps on random mini-batches of
``lm_batch_size``), the random forest is fitted once, the others by gradient.

Checkpoints (``run_dir``): ``last.pt`` after every epoch (actor, optimiser, epoch, RNG
state, history) and ``best.pt`` (the actor with the lowest validation loss, readable by
``pilerl.policies.load_actor``). Both are verified checkpoint files
(``pilerl.policies.checkpoint_file``: zip CRCs and a SHA-256 checked, read with
``torch.load(weights_only=True)``, sizes checked before allocating): no code runs on load
and a damaged file is refused with ``CheckpointError``. A run given the ``run_dir`` of a
killed run resumes from ``last.pt`` and ends with the same weights as an uninterrupted
run: the batch order of epoch k is drawn from a generator seeded with (seed, k), and the
dropout RNG state is restored.

The gradient step reads one contiguous tensor: the controller inputs (s, s') of the whole
training set are normalised once, and each batch is a row gather from them, so a step
pays for the model and RAdam, not for TensorDict indexing or TorchRL's ``BCLoss``
wrapper. It computes exactly what ``BCLoss(actor, loss_function="mse")`` on the indexed
tensordict computed (the same element-wise normalisation, forward, dropout draws and
mean), so a fixed seed gives bit-identical losses and weights (pinned by
``tests/training/test_training.py::test_gradient_step_matches_the_bcloss_path``). RAdam's
step runs over all parameters at once (``pilerl.training.flat_radam.FlatRAdam``: torch's
operations in torch's order, one kernel each instead of one per parameter), bit for bit.
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import torch
import torch.nn.functional as F
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from tqdm import tqdm

from pilerl.layout import RunLayout
from pilerl.policies import actor_policy, policy_actor, save_actor
from pilerl.policies.actors import RandomForestActor
from pilerl.policies.checkpoint import actor_config_from_json, rebuild_policy
from pilerl.policies.checkpoint_file import (
    CheckpointError,
    load_optimizer_state,
    parse_json,
    read_checkpoint,
    write_checkpoint,
)
from pilerl.policies.levenberg_marquardt import fit_lm
from pilerl.policies.policy import SensorPolicy
from pilerl.policies.registry import get_spec

from .draw_ahead import MasksAhead, masks_ahead
from .dropout_masks import check_dropout_masks, dropout_masks
from .flat_radam import FlatRAdam

log = logging.getLogger(__name__)
TRAINERS = ("gradient", "levenberg_marquardt", "fit")
RUN_FORMAT = "pilerl.bc_run"
RUN_VERSION = 2  # 2: with a SHA-256 of the content (pilerl.policies.checkpoint_file)
LEGACY_RUN_VERSIONS = (1,)
EVAL_BATCH = 8192  # rows per forward pass when computing a validation loss
DEFAULT_DROPOUT_MASKS = "bernoulli"  # train_bc's masks when BCSettings.dropout_masks is None


@dataclass(frozen=True)
class BCSettings:
    """Training settings (the paper's defaults).

    Attributes:
        epochs: passes over the training data.
        batch_size: samples per gradient step.
        learning_rate: RAdam's learning rate.
        seed: seeds the batch order and dropout (seed the weights before ``make_actor``).
        trainer: ``gradient``, ``levenberg_marquardt`` or ``fit``; ``None`` = the
            controller's default.
        lm_iterations, lm_batch_size: Levenberg-Marquardt steps per epoch and rows per step.
        dropout_masks: how dropout draws its masks in training
            (``pilerl.training.dropout_masks``): ``bernoulli`` (torch's own, element by
            element), ``packed`` (16-bit slices of 64-bit random words, about 6x cheaper
            to draw; other draws, the same distribution); ``None`` = the trainer's
            default: ``bernoulli`` for ``train_bc`` (bit-identical to earlier runs),
            ``packed`` for ``train_bc_ensemble``.
    """

    epochs: int = 150
    batch_size: int = 512
    learning_rate: float = 1e-3
    seed: int = 0
    trainer: str | None = None
    lm_iterations: int = 10
    lm_batch_size: int = 4096
    dropout_masks: str | None = None

    def __post_init__(self) -> None:
        check_dropout_masks(self.dropout_masks, "BCSettings.dropout_masks")
        if self.trainer not in (None, *TRAINERS):
            raise ValueError(
                f"BCSettings.trainer: unknown {self.trainer!r}; known: "
                f"{list(TRAINERS)} (None = the controller's default)"
            )
        if self.epochs < 1 or self.batch_size < 1:
            raise ValueError(f"BCSettings: epochs and batch_size must be >= 1, got {self}")
        if not (math.isfinite(self.learning_rate) and self.learning_rate > 0):
            raise ValueError(f"BCSettings.learning_rate: must be > 0, got {self.learning_rate}")


def validation_loss(actor: TensorDictModule, data: TensorDict) -> float:
    """Mean squared error between the actor's action (eval mode) and the demonstrated one."""
    policy = actor_policy(actor)
    was_training = policy.training
    policy.eval()
    total, count = 0.0, 0
    with torch.no_grad():
        for start in range(0, data.batch_size[0], EVAL_BATCH):
            chunk = data[start : start + EVAL_BATCH]
            predicted = actor(chunk.select(*policy.in_keys).clone())["action"]
            total += float(((predicted - chunk["action"]) ** 2).sum())
            count += predicted.numel()
    policy.train(was_training)
    return total / count


def epochs_for_steps(rows: int, batch_size: int, gradient_steps: int) -> int:
    """Epochs that give about ``gradient_steps`` steps of ``batch_size`` over ``rows`` (>= 1).

    Gives datasets of different sizes the same training budget: the paper's 150 epochs of
    D_II (16k rows, 33 steps of 512 each) are about 5,000 steps, one epoch of D_I at 500 Hz
    (450k rows) is already 880.
    """
    if gradient_steps < 1 or batch_size < 1 or rows < 1:
        raise ValueError(
            f"epochs_for_steps: rows, batch_size and gradient_steps must be >= 1, got "
            f"{rows}, {batch_size}, {gradient_steps}"
        )
    return max(1, round(gradient_steps / math.ceil(rows / batch_size)))


def train_bc(
    actor: TensorDictModule,
    train: TensorDict,
    validation: TensorDict | None,
    settings: BCSettings,
    *,
    run_dir: str | Path | None = None,
    logger=None,
    progress: bool = True,
    draw_ahead: bool = False,
    draw_packed_ahead: bool = False,
) -> tuple[TensorDictModule, list[dict]]:
    """Fit ``actor`` to ``train``; returns (the trained actor, one history row per epoch).

    Args:
        actor: from ``pilerl.policies.make_actor`` (the random forest is fitted, not
            trained by gradient).
        train, validation: transitions with the actor's sensor keys and ``action``.
        run_dir: where ``last.pt`` / ``best.pt`` go; a ``last.pt`` there is resumed.
        logger: a TorchRL logger (``log_scalar(name, value, step)``), or ``None``.
        draw_ahead: draw torch's dropout masks (``bernoulli``) a step ahead on a second
            thread (``pilerl.training.draw_ahead``): bit-identical results, faster where
            a second core is idle, slower where it is not. With ``packed`` masks it is
            refused (it draws torch's masks: two generators asked for). Where there is
            nothing to draw ahead (the Levenberg-Marquardt trainer, whose steps are not
            drawn ahead, the forest's fit, a controller without dropout with p > 0) training
            runs as without it and one warning per call says it has no effect: the
            option changes where masks are drawn, never what is computed, so an error
            would stop a sweep over controllers (NNet trains with Levenberg-Marquardt by
            default) for a setting that cannot change its results.
        draw_packed_ahead: the same for ``packed`` masks (``settings.dropout_masks`` must
            be ``packed``): bit-identical to packed masks drawn in the step.
    """
    policy = actor_policy(actor)
    trainer = settings.trainer or get_spec(policy.config.controller).trainer
    if isinstance(actor, RandomForestActor) or trainer == "fit":
        if not isinstance(actor, RandomForestActor):
            raise ValueError(
                f"trainer 'fit' is for the random forest, not {policy.config.controller!r}"
            )
        if draw_ahead or draw_packed_ahead:
            _draw_ahead_unused(
                "the random forest is fitted, it has no dropout",
                "draw_packed_ahead" if draw_packed_ahead else "draw_ahead",
            )
        return _fit_forest(actor, train, validation, run_dir=run_dir, logger=logger)
    torch.manual_seed(settings.seed)
    # only what training reads: indexing a batch then copies 8 columns, not the whole
    # transition (next readings, flags, time...)
    train = train.select(*policy.in_keys, "action")
    optimizer = torch.optim.RAdam(policy.parameters(), lr=settings.learning_rate)
    history: list[dict] = []
    best = math.inf
    layout = RunLayout(run_dir) if run_dir is not None else None
    if layout is not None and layout.bc_state.exists():
        policy, optimizer, history, best = _resume(layout.bc_state, settings, policy.config)
        actor = policy_actor(policy)
    # torch's RAdam step computed over all parameters at once (bit-identical)
    flat_radam = FlatRAdam(optimizer)
    # the controller inputs of every row, normalised once: a batch is a row gather
    inputs, attention_inputs = policy.controller_inputs(train)
    target = train["action"]
    n = train.batch_size[0]
    epochs = range(len(history), settings.epochs)
    bar = tqdm(
        epochs,
        desc="behaviour cloning",
        unit="epoch",
        disable=not progress,
        initial=len(history),
        total=settings.epochs,
    )
    masks = settings.dropout_masks or DEFAULT_DROPOUT_MASKS
    if draw_ahead and masks != "bernoulli":
        raise ValueError(
            f"train_bc: draw_ahead draws torch's bernoulli masks, not {masks!r} (packed masks "
            "are drawn ahead with draw_packed_ahead=True)"
        )
    if draw_packed_ahead and masks != "packed":
        raise ValueError(
            f"train_bc: draw_packed_ahead draws packed masks, not {masks!r} (set "
            "BCSettings.dropout_masks='packed', or draw torch's masks ahead with draw_ahead)"
        )
    ahead = draw_ahead or draw_packed_ahead

    def one_row() -> object:
        s_att = None if attention_inputs is None else attention_inputs[:1]
        return policy.controller(inputs[:1], s_att)

    # masks drawn ahead replace the dropout layers; otherwise they draw in the step
    drawn_masks = (
        masks_ahead(policy.controller, one_row, masks)
        if ahead and trainer == "gradient"
        else dropout_masks(policy, masks)
    )
    with drawn_masks as feed:
        if ahead and feed is None:
            _draw_ahead_unused(
                f"the {trainer} trainer's steps are not drawn ahead"
                if trainer != "gradient"
                else f"{policy.config.controller!r} has no dropout layer with p > 0",
                "draw_packed_ahead" if draw_packed_ahead else "draw_ahead",
            )
        for epoch in bar:
            policy.train()
            generator = torch.Generator().manual_seed(settings.seed * 1_000_003 + epoch)
            if trainer == "levenberg_marquardt":
                fit_lm(
                    policy.controller,
                    inputs,
                    target,
                    iterations=settings.lm_iterations,
                    batch_size=min(settings.lm_batch_size, n),
                    generator=generator,
                )
                train_loss = validation_loss(actor, train)
            else:
                order = torch.randperm(n, generator=generator)
                train_loss = _gradient_epoch(
                    policy,
                    flat_radam,
                    inputs,
                    attention_inputs,
                    target,
                    order,
                    settings.batch_size,
                    feed,
                )
            row = {"epoch": epoch + 1, "train_loss": train_loss}
            if validation is not None:
                row["validation_loss"] = validation_loss(actor, validation)
            history.append(row)
            _log(logger, row)
            score = row.get("validation_loss", row["train_loss"])
            if layout is not None:
                if score < best:
                    save_actor(layout.best_actor, policy)
                best = min(best, score)
                flat_radam.store()
                _save_run(layout.bc_state, policy, optimizer, history, best, settings)
            bar.set_postfix({k: f"{v:.4g}" for k, v in row.items() if k != "epoch"})
    bar.close()
    flat_radam.store()
    policy.eval()
    return actor, history


def _gradient_epoch(
    policy: SensorPolicy,
    optimizer: FlatRAdam,
    inputs: torch.Tensor,
    attention_inputs: torch.Tensor | None,
    target: torch.Tensor,
    order: torch.Tensor,
    batch_size: int,
    feed: MasksAhead | None = None,
) -> float:
    """One pass of RAdam steps over the rows in ``order``; returns the mean training loss.

    ``inputs`` / ``attention_inputs`` are the normalised controller inputs s, s' of every
    row (``SensorPolicy.controller_inputs``), ``target`` the demonstrated actions;
    ``feed``, if given, draws the dropout masks ahead (``pilerl.training.draw_ahead``).
    """
    total = 0.0
    starts = range(0, len(order), batch_size)
    if feed is not None:
        feed.start_epoch([len(order[start : start + batch_size]) for start in starts])
    for start in starts:
        rows = order[start : start + batch_size]
        if feed is not None:
            feed.next_step()
        # index_select: the same rows as inputs[rows], without advanced indexing's overhead
        s_att = None if attention_inputs is None else attention_inputs.index_select(0, rows)
        predicted = policy.controller(inputs.index_select(0, rows), s_att).action
        # BCLoss's "mse": the element-wise squared error, then its mean
        loss = F.mse_loss(predicted, target.index_select(0, rows), reduction="none").mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        total += float(loss.detach()) * len(rows)
    if feed is not None:
        feed.end_epoch()
    return total / len(order)


def _draw_ahead_unused(reason: str, option: str = "draw_ahead") -> None:
    log.warning("train_bc: %s has no effect: %s", option, reason)


def _fit_forest(
    actor: RandomForestActor,
    train: TensorDict,
    validation: TensorDict | None,
    *,
    run_dir: str | Path | None,
    logger,
) -> tuple[TensorDictModule, list[dict]]:
    actor.fit(train)
    row = {"epoch": 1, "train_loss": validation_loss(actor, train)}
    if validation is not None:
        row["validation_loss"] = validation_loss(actor, validation)
    _log(logger, row)
    if run_dir is not None:
        save_actor(RunLayout(run_dir).best_actor, actor)
    return actor, [row]


def _log(logger, row: dict) -> None:
    if logger is None:
        return
    for name, value in row.items():
        if name != "epoch":
            logger.log_scalar(name, value, step=row["epoch"])


def _save_run(
    path: Path, policy, optimizer, history: list[dict], best: float, settings: BCSettings
) -> None:
    payload = {
        "format": RUN_FORMAT,
        "version": RUN_VERSION,
        "settings": json.dumps(asdict(settings)),
        "actor_config": json.dumps(policy.config.to_json(), allow_nan=False),
        "state_dict": {k: v.detach().clone() for k, v in policy.state_dict().items()},
        "optimizer": optimizer.state_dict(),
        "history": json.dumps(history),
        "best": best,
        "rng_state": torch.get_rng_state(),
    }
    # a run whose losses are not finite yet (NaN history, best = inf) can still resume
    write_checkpoint(path, payload, allow_infinite=lambda where: where == "best")


def _resume(path: Path, settings: BCSettings, wanted):
    """The training state in ``path``; refused when it trains another model or setting."""
    payload = read_checkpoint(
        path,
        expected_format=RUN_FORMAT,
        version=RUN_VERSION,
        legacy_versions=LEGACY_RUN_VERSIONS,
        allow_infinite=lambda where: where == "best",
        what="training checkpoint",
    )
    saved = parse_json(path, payload.get("settings"), "settings")
    now = _as_resumed(asdict(settings))
    before = _as_resumed(saved) if isinstance(saved, dict) else {}
    differing = sorted(
        key
        for key in set(before) | set(now)
        if key != "epochs" and before.get(key, "<unset>") != now.get(key, "<unset>")
    )
    if not isinstance(saved, dict) or differing:
        raise ValueError(
            f"{path}: was trained with {saved}, not {asdict(settings)} (they differ in "
            f"{differing or ['settings']}); use a new run directory"
        )
    config = actor_config_from_json(path, payload.get("actor_config"), "actor_config")
    if config.to_json() != wanted.to_json():
        differing = sorted(
            key
            for key in set(config.to_json()) | set(wanted.to_json())
            if config.to_json().get(key) != wanted.to_json().get(key)
        )
        raise ValueError(
            f"{path}: holds a {config.controller!r} actor ({_inputs(config)}), not the "
            f"{wanted.controller!r} ({_inputs(wanted)}) asked for; they differ in {differing}. "
            "Use a new run directory."
        )
    policy = rebuild_policy(path, config, payload.get("state_dict"), "state_dict")
    optimizer = torch.optim.RAdam(policy.parameters(), lr=settings.learning_rate)
    load_optimizer_state(path, optimizer, payload.get("optimizer"), "optimizer")
    history = parse_json(path, payload.get("history"), "history", allow_non_finite=True)
    best, rng_state = payload.get("best"), payload.get("rng_state")
    if not isinstance(history, list) or not isinstance(best, float):
        raise CheckpointError(f"{path}: history or best loss missing")
    if not isinstance(rng_state, torch.Tensor) or rng_state.shape != torch.get_rng_state().shape:
        raise CheckpointError(f"{path}: rng_state is not torch's generator state")
    torch.set_rng_state(rng_state)
    return policy, optimizer, history, best


def _as_resumed(settings: dict) -> dict:
    """Training settings as a resume compares them (``epochs`` may grow): in ``train_bc``
    ``dropout_masks`` ``None`` means torch's draws, the same as ``bernoulli``, and a run
    saved before the key existed drew torch's masks too."""
    return {**settings, "dropout_masks": settings.get("dropout_masks") or DEFAULT_DROPOUT_MASKS}


def _inputs(config) -> str:
    sensors = ", ".join(config.sensors)
    attention = getattr(config, "attention_sensors", None)
    return f"sensors {sensors}" + (f"; attention {', '.join(attention)}" if attention else "")
