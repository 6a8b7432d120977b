"""Counting scoops: the experience a fine-tuning run costs, in episodes as well as frames.

On a real wheel loader each scoop (one episode: approach, fill, lift) costs fuel, wear
and an operator's time, and a failed or tipped one costs more; frames (control steps)
alone hide that. ``count_scoops`` reads a collected batch: every step whose
``("next", "done")`` is set ends a scoop; its ``success`` and ``tipped`` flags come from
the training env (``("next", "success")`` of a single env, or the ``("next", "info")``
columns ``BATCH_INFO_KEYS`` of a batched one). A scoop cut by the end of a batch is
counted in the batch where it ends; evaluation episodes are never in a collected batch,
so they are not counted as experience.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict import TensorDictBase

from pilerl.sim.torchrl_env import INFO_KEY

from .envs import BATCH_INFO_KEYS, SCOOP_SUCCESS_KEY, SUCCESS_KEY, TIPPED_KEY


@dataclass(frozen=True)
class ScoopCount:
    """What one collected batch holds.

    Attributes:
        frames: environment steps (control steps).
        scoops: episodes that ended in the batch.
        failed: of those, episodes that did not succeed (tipped ones included).
        tipped: of those, episodes that ended with the machine tipped.
    """

    frames: int
    scoops: int
    failed: int
    tipped: int


def _flag(batch: TensorDictBase, name: str) -> torch.Tensor | None:
    """The ``next`` step's ``name`` flag (bool, flat over the batch), or ``None``."""
    keys = batch.keys(True)
    if name == SUCCESS_KEY and ("next", SUCCESS_KEY) in keys:
        return batch["next", SUCCESS_KEY].reshape(-1) > 0.5
    if ("next", INFO_KEY) in keys:
        column_name = SCOOP_SUCCESS_KEY if name == SUCCESS_KEY else name
        column = batch["next", INFO_KEY][..., BATCH_INFO_KEYS.index(column_name)].reshape(-1)
        return torch.nan_to_num(column, nan=0.0) > 0.5
    return None


def count_scoops(batch: TensorDictBase) -> ScoopCount:
    """Frames, ended scoops and failed / tipped scoops of a collected batch.

    Raises ``KeyError`` when scoops ended but the batch does not say whether they
    succeeded (a training env without ``success``): failures would silently read 0.
    """
    done = batch["next", "done"].reshape(-1)
    scoops = int(done.sum())
    failed = tipped = 0
    if scoops:
        success = _flag(batch, SUCCESS_KEY)
        if success is None:
            raise KeyError(
                "count_scoops: the batch has no ('next', 'success') nor ('next', 'info') entry; "
                "collect with pilerl.rl.envs.make_training_env"
            )
        failed = int((done & ~success).sum())
        tip = _flag(batch, TIPPED_KEY)
        tipped = int((done & tip).sum()) if tip is not None else 0
    return ScoopCount(frames=batch.numel(), scoops=scoops, failed=failed, tipped=tipped)
