"""Many seeds of one behaviour-cloning configuration at once (the paper's Fig. 4).

The N members (same controller and data, different initial weights) are trained together
with ``torch.func``: their parameters are stacked, the MSE of all members is evaluated by
one ``vmap``-ed call per batch (dropout drawn independently per member), and RAdam steps
the stacked tensors. RAdam is element-wise, so this is exactly N independent optimisers;
every member sees the same batches in the same order, as N separate runs with the same
seed would. The result is each member's training and validation loss per epoch, for
mean +- std curves. Every member is trained by gradient (RAdam), NNet included: its
Levenberg-Marquardt default applies to single runs (``train_bc``).

Dropout masks are ``packed`` by default (``BCSettings.dropout_masks``, see
``pilerl.training.dropout_masks``): each step draws a layer's masks for every member with
one call, from 16-bit slices of 64-bit random words, and hands each member its own as a
buffer. ``bernoulli`` keeps torch's own draws inside ``vmap`` (what ran before; about
six times the cost to draw). Both draw from the global generator.

Members are trained ``members_per_pass`` at a time (groups of consecutive seeds, one
after the other): per member, a pass of 100 DANNets costs more than a pass of 16 (its
activations no longer fit the caches; measured with ``benchmarks/bc_throughput.py``,
docs/performance.md), and memory stays that of one pass. A pass trains exactly what
``train_bc_ensemble`` of its seeds alone trains: an ensemble of at most
``members_per_pass`` seeds is the one-pass result, bit for bit; a larger one draws each
pass's dropout masks on its own.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from tensordict import TensorDict
from torch.func import functional_call, stack_module_state, vmap
from tqdm import tqdm

from pilerl.io import atomic_path
from pilerl.policies import SensorPolicy
from pilerl.policies.config import ActorConfig
from pilerl.policies.registry import build_policy

from .bc import EVAL_BATCH, BCSettings
from .dropout_masks import GivenMaskDropout, dropout_layers, packed_keep_masks, replace_dropout

MEMBERS_PER_PASS = 16  # members trained together (see the module docstring)
DEFAULT_DROPOUT_MASKS = "packed"  # the masks when BCSettings.dropout_masks is None


@dataclass
class EnsembleResult:
    """Per-member losses: arrays of shape (members, epochs)."""

    seeds: list[int]
    train_loss: np.ndarray
    validation_loss: np.ndarray | None
    members: list[SensorPolicy]


def _readings(policy: SensorPolicy, data: TensorDict) -> tuple[torch.Tensor, torch.Tensor]:
    return torch.cat([data[k] for k in policy.in_keys], -1), data["action"]


def train_bc_ensemble(
    config: ActorConfig,
    seeds: Sequence[int],
    train: TensorDict,
    validation: TensorDict | None,
    settings: BCSettings,
    *,
    progress: bool = True,
    members_per_pass: int = MEMBERS_PER_PASS,
) -> EnsembleResult:
    """Train one member per seed (initial weights from ``torch.manual_seed(seed)``),
    ``members_per_pass`` at a time."""
    if members_per_pass < 1 or not seeds:
        raise ValueError(
            f"train_bc_ensemble: needs seeds and members_per_pass >= 1, got {len(seeds)} "
            f"seeds and members_per_pass={members_per_pass}"
        )
    passes = [
        _train_pass(config, seeds[i : i + members_per_pass], train, validation, settings, progress)
        for i in range(0, len(seeds), members_per_pass)
    ]
    return EnsembleResult(
        seeds=list(seeds),
        train_loss=np.concatenate([p.train_loss for p in passes]),
        validation_loss=(
            np.concatenate([p.validation_loss for p in passes]) if validation is not None else None
        ),
        members=[member for p in passes for member in p.members],
    )


def _train_pass(
    config: ActorConfig,
    seeds: Sequence[int],
    train: TensorDict,
    validation: TensorDict | None,
    settings: BCSettings,
    progress: bool,
) -> EnsembleResult:
    """The members of ``seeds`` trained together: one ``vmap``-ed loss per batch."""
    members = []
    for seed in seeds:
        torch.manual_seed(seed)
        members.append(build_policy(config))
    if any(m.config.controller == "rf" for m in members):
        raise ValueError("train_bc_ensemble: the random forest is not a neural controller")
    params, buffers = stack_module_state(members)
    base = copy.deepcopy(members[0]).to("meta")
    readings, target = _readings(members[0], train)
    val = _readings(members[0], validation) if validation is not None else None
    dropouts = {}  # packed masks: dropout layer -> its DropoutSite (p, one row's shape)
    if (settings.dropout_masks or DEFAULT_DROPOUT_MASKS) == "packed":
        dropouts = dropout_layers(members[0], lambda: members[0](*readings[:1].split(1, dim=-1)))
        replace_dropout(base, GivenMaskDropout)

    def predict(p, b, x):
        """One member's action for readings x [B, n_inputs] (columns in ``in_keys`` order)."""
        return functional_call(base, (p, b), tuple(x.split(1, dim=-1)))[0]

    def batch_loss(p, b, x, y):
        return ((predict(p, b, x) - y) ** 2).mean()

    losses_of = vmap(batch_loss, in_dims=(0, 0, None, None), randomness="different")
    predict_all = vmap(predict, in_dims=(0, 0, None), randomness="different")
    optimizer = torch.optim.RAdam(list(params.values()), lr=settings.learning_rate)
    n = readings.shape[0]
    train_hist, val_hist = [], []
    for epoch in tqdm(
        range(settings.epochs), desc=f"ensemble x{len(seeds)}", unit="epoch", disable=not progress
    ):
        base.train()
        order = torch.randperm(
            n, generator=torch.Generator().manual_seed(settings.seed * 1_000_003 + epoch)
        )
        total = torch.zeros(len(seeds))
        for start in range(0, n, settings.batch_size):
            idx = order[start : start + settings.batch_size]
            masks = {
                f"{name}.mask": packed_keep_masks([(len(seeds), len(idx), *site.shape)], site.p)[0]
                for name, site in dropouts.items()
            }
            losses = losses_of(params, buffers | masks, readings[idx], target[idx])
            optimizer.zero_grad()
            losses.sum().backward()
            optimizer.step()
            total += losses.detach() * len(idx)
        train_hist.append((total / n).numpy())
        if val is not None:
            base.eval()
            with torch.no_grad():
                errors = torch.zeros(len(seeds))
                for start in range(0, val[0].shape[0], EVAL_BATCH):
                    x, y = val[0][start : start + EVAL_BATCH], val[1][start : start + EVAL_BATCH]
                    errors += ((predict_all(params, buffers, x) - y) ** 2).sum(dim=(1, 2))
            val_hist.append((errors / val[1].numel()).numpy())
    for i, member in enumerate(members):
        saved = member.state_dict()
        member.load_state_dict({k: {**params, **buffers}[k][i].detach().clone() for k in saved})
        member.eval()
    return EnsembleResult(
        seeds=list(seeds),
        train_loss=np.stack(train_hist, axis=1),
        validation_loss=np.stack(val_hist, axis=1) if val_hist else None,
        members=members,
    )


def write_ensemble_curves(result: EnsembleResult, path: str | Path) -> Path:
    """Mean and std over members per epoch, as CSV: ``epoch, train_mean, train_std`` and,
    with validation data, ``validation_mean, validation_std``."""
    columns = {
        "epoch": np.arange(1, result.train_loss.shape[1] + 1),
        "train_mean": result.train_loss.mean(0),
        "train_std": result.train_loss.std(0),
    }
    if result.validation_loss is not None:
        columns["validation_mean"] = result.validation_loss.mean(0)
        columns["validation_std"] = result.validation_loss.std(0)
    path = Path(path)
    with atomic_path(path) as tmp:
        np.savetxt(
            tmp,
            np.column_stack(list(columns.values())),
            delimiter=",",
            header=",".join(columns),
            comments="",
            fmt="%.8g",
        )
    return path
